"""The per-configuration loop the scene benchmarks share: a row each, skips recorded, renderers released."""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable

from ..errors import GuacaError


def config_rows(
    configs: Iterable[tuple[dict, Callable[[], object]]],
    measure: Callable[[object, dict], None],
    report: Callable[[dict], None],
    t0: float,
    budget_s: float | None,
) -> list[dict]:
    """One row per (row, make_renderer): `measure(renderer, row)` fills it, `report(row)` prints it (skipped or not).

    A row is skipped (its `skipped` says why) once `budget_s` seconds since `t0` are spent (the first
    configuration always runs, whatever the scene's reference took), or where the device refuses the
    configuration or a frame fails; a skip is recorded, not fatal. `seconds` is each row's own time.
    """
    rows: list[dict] = []
    for row, make in configs:
        t1 = time.perf_counter()
        if rows and budget_s and t1 - t0 > budget_s:
            row["skipped"] = f"scene time budget ({budget_s:g} s) spent"
        else:
            try:
                r = make()
            except GuacaError as exc:  # a sample count or method this device refuses
                row["skipped"] = str(exc)
            else:
                try:
                    measure(r, row)
                except GuacaError as exc:
                    row["skipped"] = str(exc)
                finally:
                    r.release()
        row["seconds"] = time.perf_counter() - t1
        rows.append(row)
        report(row)
    return rows


def flip_cell(row: dict) -> str:
    """A row's FLIP for a table (— where flip-evaluator was not installed)."""
    return f"{row['flip']:.4f}" if row.get("flip") is not None else "—"


def stored_cell(row: dict) -> str:
    """A row's stored fragments for a table, with those an overflowing pool dropped (the image lacks them)."""
    fragments = row["fragments"]
    stored = fragments.get("stored", "—")
    return f"{stored} (+{fragments['overflow']} dropped)" if fragments.get("overflow") else f"{stored}"

"""`raster_order: auto` for methods with early termination: front to back while it culls, else back to front.

Front to back, a pixel's near fragments arrive first and saturate it, and early termination culls
the farther ones before any insertion walk (the hairballs: most of their fragments). But each
fragment then walks its whole list to the tail. Where early termination culls little, back to
front is cheaper: each fragment goes in at its list's head. On the H100 at 1024² (presort_lf_et,
benchmarks/results/h100/final_75fbdc5/): the dragons, of which it culls ~2 %, 2.52 -> 2.32 ms at
1 sample and 6.97 -> 5.34 at 4; hairball_v1, of which it culls 84 %, 4.68 -> 6.03 and 9.72 ->
13.08; Sponza (7 %) within 0.05 ms either way.

How much a frame culls is known only once it is drawn, so the choice follows counted frames: a
frame drawn front to back measures it, and the next frames go back to front when it was under
CULL_FRACTION. Back to front culls nothing, so nothing is measured there: a frame goes front to
back again after REPROBE_FRAMES frames, or at once when the fragments reaching insertion change by
more than REPROBE_CHANGE (a new view or scene). Images are the same either way: the composite
stops at the saturation threshold, which is where early termination stops inserting.
"""

from __future__ import annotations

FRONT_TO_BACK = "depth"
BACK_TO_FRONT = "back_to_front"


class DepthDirection:
    """Which way `auto` takes triangles in depth, from the early termination counted in earlier frames."""

    CULL_FRACTION = 0.05  # culls under 5 % of the fragments: back to front pays (dragons 2 %, Sponza 7 %)
    REPROBE_FRAMES = 64  # back-to-front frames before one is drawn front to back to measure again
    REPROBE_CHANGE = 0.25  # relative change of the fragments that sends the next frame front to back

    def __init__(self) -> None:
        self.order = FRONT_TO_BACK  # the first frame measures
        self.reason = "first frame: front to back measures how much early termination culls"
        self._measured = 0  # fragments reaching insertion in the last front-to-back frame
        self._since = 0  # back-to-front frames since then

    def observe(self, order: str, stored: int, culled: int) -> None:
        """Take a counted frame drawn in `order`: `stored` fragments inserted, `culled` refused by early termination."""
        total = stored + culled
        if order == FRONT_TO_BACK:
            share = culled / total if total else 1.0
            self._measured, self._since = total, 0
            if total and share < self.CULL_FRACTION:
                self.order = BACK_TO_FRONT
                self.reason = f"early termination culled {share:.1%} front to back (< {self.CULL_FRACTION:.0%})"
            else:
                self.order = FRONT_TO_BACK
                self.reason = f"early termination culls {share:.1%} front to back (>= {self.CULL_FRACTION:.0%})"
        elif order == BACK_TO_FRONT:
            self._since += 1
            changed = abs(total - self._measured) > self.REPROBE_CHANGE * max(self._measured, 1)
            if changed or self._since >= self.REPROBE_FRAMES:
                self.order = FRONT_TO_BACK
                self.reason = (
                    f"fragments changed by more than {self.REPROBE_CHANGE:.0%}: measuring again front to back"
                    if changed
                    else f"{self.REPROBE_FRAMES} frames back to front: measuring again front to back"
                )

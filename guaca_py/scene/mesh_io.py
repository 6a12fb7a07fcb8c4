"""Load triangle meshes from files (OBJ, PLY, STL, glTF/GLB, ...) into MeshData via trimesh."""

from __future__ import annotations

import io
import os
import re
from collections.abc import Callable
from pathlib import Path

import numpy as np

from ..errors import ConfigError
from ..numeric import FLOAT32_MAX
from ..yaml_source import file_problem
from .nodes import MeshData
from .texture import decode_image

MESH_FORMATS_HINT = "supported formats: .obj, .ply, .stl, .glb, .gltf (anything trimesh reads)"


def file_error(
    p: Path, file_for_errors: str | Path | None, line: int | None, key: str | None
) -> Callable[[str, str], ConfigError]:
    """`fail(reason, hint)` for a model file: the error cites the scene file's line and key where it was named."""

    def fail(reason: str, hint: str) -> ConfigError:
        return ConfigError(reason, file_for_errors if file_for_errors is not None else p, line, key, hint)

    return fail


def check_file(path: str | Path, fail: Callable[[str, str], ConfigError], what: str) -> None:
    """Raise fail(...) unless `path` is a readable regular file; `what` names it ("mesh file", "buffers[0].uri")."""
    problem = file_problem(path)
    if problem is not None:
        raise fail(
            f"{what} {problem}: {os.fspath(path)!r}",
            "check the path; relative paths resolve against the file naming them",
        )


def _smooth_normals(positions: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Area-weighted vertex normals; done here so trimesh never needs scipy for it."""
    tri = positions[faces]
    face_n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])  # length = 2 * area
    normals = np.zeros_like(positions)
    for k in range(3):
        np.add.at(normals, faces[:, k], face_n)
    return normals


def _unitize(normals: np.ndarray) -> np.ndarray:
    """Normalise rows; zero rows (isolated or degenerate vertices) become +Z so all are unit."""
    length = np.linalg.norm(normals, axis=1, keepdims=True)
    ok = (length[:, 0] > 1e-12) & np.isfinite(length[:, 0])
    out = np.tile(np.array([0.0, 0.0, 1.0]), (normals.shape[0], 1))
    out[ok] = normals[ok] / length[ok]
    return out


def _file_normals(mesh) -> np.ndarray | None:
    """Vertex normals the file itself provided, or None (asking trimesh would compute some)."""
    cache = getattr(getattr(mesh, "_cache", None), "cache", None)
    if cache is None:  # trimesh internals changed: accept its normals
        return np.asarray(mesh.vertex_normals, dtype=np.float64)
    normals = cache.get("vertex_normals")
    if normals is None or np.shape(normals) != np.shape(mesh.vertices):
        return None
    return np.asarray(normals, dtype=np.float64)


def _texcoords(mesh, count: int) -> np.ndarray:
    """Per-vertex UVs when the file has them, else zeros so every MeshData carries texcoords."""
    visual = getattr(mesh, "visual", None)
    uv = getattr(visual, "uv", None) if getattr(visual, "kind", None) == "texture" else None
    if uv is None or np.shape(uv) != (count, 2):
        return np.zeros((count, 2), dtype=np.float32)
    return np.nan_to_num(np.asarray(uv, dtype=np.float32))


_TEXT_FORMATS = (".obj", ".off")  # text formats whose non-UTF-8 bytes send trimesh to an undeclared charset detector


def _side_file(path: Path, where: str, fail: Callable[[str, str], ConfigError]) -> None:
    """Refuse a file an OBJ or MTL names when it exists but is no regular file (a FIFO would block forever).

    A missing one is left to trimesh, which draws the mesh without it.
    """
    problem = file_problem(path)
    if problem is not None and problem != "not found":
        raise fail(f"{where} {problem}: {os.fspath(path)!r}", "name a regular file")


def _named_files(line: str, base: Path) -> list[Path]:
    """The files an `mtllib` or `map_*` line names: the whole rest of the line when it names a file, else each word."""
    rest = line.split(None, 1)[1].strip() if len(line.split(None, 1)) > 1 else ""
    if not rest:
        return []
    whole = base / rest
    return [whole] if file_problem(whole) is None else [base / word for word in rest.split()]


def check_mesh_source(p: Path, fail: Callable[[str, str], ConfigError]) -> None:
    """What trimesh would read wrongly or hang on: an OBJ's face index 0 and its side files, a binary STL's count."""
    suffix = p.suffix.lower()
    if suffix == ".stl":
        _check_stl(p, fail)
    if suffix != ".obj":
        return
    text = p.read_bytes().decode("latin-1")
    for number, line in enumerate(text.splitlines(), 1):
        word = line.split(None, 1)[0] if line.strip() else ""
        if word == "f":
            for ref in line.split()[1:]:
                first = ref.split("/", 1)[0]
                if re.fullmatch(r"[-+]?0+", first):
                    raise fail(
                        f"{p}:{number}: face index 0 (OBJ indices start at 1)", "repair the mesh in a modelling tool"
                    )
        elif word == "mtllib":
            for mtl in _named_files(line, p.parent):
                _side_file(mtl, f"{p}:{number}: mtllib", fail)
                if file_problem(mtl) is None:
                    _check_mtl(mtl, fail)


def _check_mtl(mtl: Path, fail: Callable[[str, str], ConfigError]) -> None:
    """Texture maps an MTL names must be regular files where they exist; the colour map must decode (size bounded)."""
    for number, line in enumerate(mtl.read_bytes().decode("latin-1").splitlines(), 1):
        word = line.split(None, 1)[0].lower() if line.strip() else ""
        if word.startswith("map_") or word in ("bump", "disp", "decal", "refl"):
            parts = line.split()
            if len(parts) > 1:
                image = mtl.parent / parts[-1]
                _side_file(image, f"{mtl}:{number}: {word}", fail)
                if word == "map_kd" and file_problem(image) is None:  # trimesh would drop a bad one silently
                    try:
                        decode_image(image, str(image))
                    except ValueError as exc:
                        raise fail(f"{mtl}:{number}: {exc}", "re-export the texture as a PNG or JPEG") from None


def _check_stl(p: Path, fail: Callable[[str, str], ConfigError]) -> None:
    """A binary STL's triangle count must match the file's size (a header claiming 2**31 is not read)."""
    size = p.stat().st_size
    with p.open("rb") as f:
        head = f.read(84)
    if size < 84 or head[:5].lower() == b"solid" and b"\0" not in head[:80]:
        return  # ASCII STL (or too short for binary): trimesh parses the text
    count = int.from_bytes(head[80:84], "little")
    if 84 + 50 * count != size:
        raise fail(
            f"{p}: its binary STL header claims {count} triangles ({84 + 50 * count} bytes) but the file has {size} bytes",
            "the file is truncated or not an STL file; export it again",
        )


#: trimesh merges duplicate vertices by hashing coordinates times 1e8 as int64: beyond this reach the
#: product overflows and distinct vertices merge (a mesh of 300 vertices at 1e12 became 60), so such a
#: mesh is kept with the vertices the file has
MERGE_REACH = 1.0e9


def check_finite(loaded, p: Path, fail: Callable[[str, str], ConfigError]) -> dict[int, float]:
    """Refuse non-finite vertices (and ones beyond float32) before trimesh's processing drops them silently;
    each geometry's largest coordinate magnitude, by id()."""
    reach = {}
    geoms = loaded.geometry.values() if hasattr(loaded, "geometry") else [loaded]
    for geom in geoms:
        vertices = getattr(geom, "vertices", None)
        if vertices is None or not len(vertices):
            continue
        v = np.asarray(vertices, dtype=np.float64)
        bad = int((~np.isfinite(v)).any(axis=1).sum())
        if bad:
            raise fail(
                f"{p} has {bad} non-finite vertex position{'s' if bad != 1 else ''} (NaN or inf)",
                "repair the mesh in a modelling tool",
            )
        reach[id(geom)] = largest = float(np.abs(v).max())
        if largest > FLOAT32_MAX:
            raise fail(
                f"{p} has vertex coordinates up to {largest:.3g}, beyond float32's range",
                "scale the model down; coordinates are uploaded as float32",
            )
    return reach


def load_checked(p: Path, trimesh, fail: Callable[[str, str], ConfigError], **kwargs):
    """trimesh.load of a mesh file with its source checked first and its raw vertices checked before processing."""
    check_mesh_source(p, fail)
    try:
        loaded = trimesh.load(**trimesh_load_args(p, trimesh), process=False, **kwargs)
    except Exception as exc:  # trimesh raises many types for unreadable input; all mean "bad file"
        raise fail(f"cannot read mesh file {p}: {exc}", MESH_FORMATS_HINT) from exc
    reach = check_finite(loaded, p, fail)
    for geom in loaded.geometry.values() if hasattr(loaded, "geometry") else [loaded]:
        if hasattr(geom, "process") and hasattr(geom, "faces"):
            faces = np.asarray(geom.faces)
            if faces.size and (faces.min() < 0 or faces.max() >= len(geom.vertices)):
                raise fail(f"{p} has face indices outside its vertex list", "repair the mesh in a modelling tool")
            if faces.size and reach.get(id(geom), 0.0) >= MERGE_REACH:
                continue  # trimesh's merge would overflow and join distinct vertices: kept as the file has them
            try:
                with np.errstate(all="ignore"):  # what a hostile file provokes is refused as a bad file, not warned
                    geom.process()  # what trimesh.load(process=True) does: merge duplicate vertices
            except Exception as exc:  # as for trimesh.load: any failure means a bad file
                raise fail(f"cannot read mesh file {p}: {exc}", MESH_FORMATS_HINT) from exc
    return loaded


def trimesh_load_args(p: Path, trimesh) -> dict:
    """trimesh.load arguments; text files that are not UTF-8 are decoded as Latin-1 here.

    Their syntax is ASCII and only comments and names may hold other bytes; Latin-1 maps every
    byte to a character, so the geometry reads the same (trimesh would import charset_normalizer).
    """
    if p.suffix.lower() in _TEXT_FORMATS:
        data = p.read_bytes()
        try:
            data.decode("utf-8")
        except UnicodeDecodeError:
            return {
                "file_obj": io.StringIO(data.decode("latin-1")),
                "file_type": p.suffix.lower().lstrip("."),
                "resolver": trimesh.resolvers.FilePathResolver(str(p)),
            }
    return {"file_obj": str(p)}


def load_mesh_file(
    path: str | Path, file_for_errors: str | Path | None = None, line: int | None = None, key: str | None = None
) -> MeshData:
    """Read a mesh file into one MeshData; scenes are flattened with their node transforms."""
    import trimesh  # imported lazily: scenes made only of primitives never pay for it

    p = Path(path)
    fail = file_error(p, file_for_errors, line, key)
    check_file(p, fail, "mesh file")
    loaded = load_checked(p, trimesh, fail)

    if isinstance(loaded, trimesh.Scene):
        parts = [g for g in loaded.geometry.values() if isinstance(g, trimesh.Trimesh) and len(g.faces)]
        if not parts:
            if loaded.geometry:
                raise fail(
                    f"{p} is not a triangle mesh (it holds no faces)",
                    "point clouds and line drawings cannot be rendered; export triangles",
                )
            raise fail(f"{p} contains no geometry", "the file is empty or not in a format trimesh understands")
        loaded = loaded.to_mesh()  # bakes each instance's scene-graph transform
    if not isinstance(loaded, trimesh.Trimesh):
        raise fail(
            f"{p} is not a triangle mesh (got {type(loaded).__name__})",
            "point clouds and line drawings cannot be rendered; export triangles",
        )

    return trimesh_to_meshdata(loaded, p.stem, fail, str(p))


def trimesh_to_meshdata(loaded, name: str, fail, what: str) -> MeshData:
    """Validate one trimesh.Trimesh and convert it to MeshData; `fail(reason, hint)` builds the error."""
    positions = np.asarray(loaded.vertices, dtype=np.float64)
    if positions.ndim != 2 or positions.shape[1] != 3:
        raise fail(
            f"{what} has vertex positions of shape {positions.shape}, not (N, 3)",
            "positions are 3 floats a vertex (a glTF POSITION accessor is VEC3)",
        )
    faces = np.asarray(loaded.faces, dtype=np.int64).reshape(-1, 3)
    if len(faces) == 0 or len(positions) == 0:
        raise fail(f"{what} has no triangles", "export the mesh with faces, not just vertices")
    if not np.all(np.isfinite(positions)):
        raise fail(f"{what} has non-finite vertex positions (NaN or inf)", "repair the mesh in a modelling tool")
    if faces.min() < 0 or faces.max() >= len(positions):
        raise fail(f"{what} has face indices outside its vertex list", "repair the mesh in a modelling tool")

    normals = _file_normals(loaded)
    if normals is None:
        normals = _smooth_normals(positions, faces)
    return MeshData(
        positions=np.ascontiguousarray(positions, dtype=np.float32),
        normals=np.ascontiguousarray(_unitize(normals), dtype=np.float32),
        texcoords=np.ascontiguousarray(_texcoords(loaded, len(positions))),
        indices=np.ascontiguousarray(faces, dtype=np.uint32),
        name=name,
    )

"""Make src/shprobe/scene/data/bunny.obj: the packaged Stanford bunny (the viewer's default object).

Run from the repository root: ``python tools/make_bunny.py [SOURCE.obj] [--faces N]`` (default
source ``$SHPROBE_TEST_DATA/meshes/bunny.obj``, the test data's 4,968-face copy of the
Stanford bunny, itself a decimation of the 69,451-triangle original).

What ships is that copy as it is: its faces' winding made consistent and outward (positive
signed volume), unreferenced vertices dropped, coordinates written with 7 significant digits
(float32 precision), the credit in the header. Measured, its size does not matter to the first
frame (the page's arrays are ~150 kB, read from shprobe's cache; docs/benchmarks.md), while a
further quadric decimation (``--faces N``: Garland & Heckbert 1997 through the
``fast-simplification`` package, not a dependency of shprobe) shows as mottled shading on the
haunch and the cheek at 3,000 and 4,000 faces under per-pixel lighting. A test checks that the
committed file equals this script's output.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
TARGET = REPO / "src" / "shprobe" / "scene" / "data" / "bunny.obj"

HEADER = """\
# The Stanford bunny for shprobe (tools/make_bunny.py): {nv} vertices, {nf} faces.
# Source: Stanford University Computer Graphics Laboratory, the Stanford 3D Scanning
# Repository (graphics.stanford.edu/data/3Dscanrep/; Turk & Levoy 1994, Cyberware scanner,
# zipper reconstruction). Terms: see bunny-LICENSE.txt beside this file.
# +Y up, metres; no normals stored (computed from the faces, which wind outward).
"""


def make(source: Path, faces: int | None = None) -> str:
    """The text of the packaged bunny made from ``source`` (decimated to ``faces`` faces when
    given)."""
    import trimesh

    m = trimesh.load(source, process=True)
    v, f = np.asarray(m.vertices, np.float64), np.asarray(m.faces, np.int64)
    if faces is not None and faces < len(f):
        import fast_simplification

        v, f = fast_simplification.simplify(v, f, target_reduction=1.0 - faces / len(f))
    d = trimesh.Trimesh(v, f, process=True)
    d.remove_unreferenced_vertices()
    trimesh.repair.fix_winding(d)
    if d.volume < 0:  # consistent but inward: turn every face
        d.invert()
    lines = [HEADER.format(nv=len(d.vertices), nf=len(d.faces))]
    lines += [f"v {x:.7g} {y:.7g} {z:.7g}\n" for x, y, z in np.asarray(d.vertices)]
    lines += [f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in np.asarray(d.faces)]
    return "".join(lines)


def main() -> None:
    data = Path(os.environ.get("SHPROBE_TEST_DATA", REPO.parent / "shared"))
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("source", nargs="?", type=Path, default=data / "meshes" / "bunny.obj")
    ap.add_argument("--faces", type=int, default=None, help="decimate to this many faces")
    a = ap.parse_args()
    text = make(a.source, a.faces)
    TARGET.parent.mkdir(parents=True, exist_ok=True)
    TARGET.write_text(text)
    print(f"wrote {TARGET} ({len(text.encode())} bytes)")


if __name__ == "__main__":
    main()

"""Make src/shprobe/scene/data/bunny.obj: the packaged Stanford bunny (the viewer's default object).

Run from the repository root: ``python tools/make_bunny.py [SOURCE.obj]`` (default
``$SHPROBE_TEST_DATA/meshes/bunny.obj``, the test data's 4,968-face copy of the Stanford
bunny). Needs ``fast-simplification`` (a dev dependency; the package itself never imports it).

The source is decimated by quadric error metrics (Garland & Heckbert 1997, the
Fast-Quadric-Mesh-Simplification implementation wrapped by ``fast-simplification``) to
:data:`TARGET_FACES` faces: enough that the silhouette and the ears stay smooth under per-pixel
shading, few enough that the page's arrays are ~70 kB (docs/benchmarks.md: the first lit frame
did not change between the source's 4,968 faces and these). Winding is made consistent and
outward (positive signed volume), unreferenced vertices dropped, coordinates written with 7
significant digits (float32 precision). A test checks that the committed file equals this
script's output.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
TARGET = REPO / "src" / "shprobe" / "scene" / "data" / "bunny.obj"
#: faces of the packaged bunny
TARGET_FACES = 3000

HEADER = """\
# The Stanford bunny, decimated for shprobe (tools/make_bunny.py): {nv} vertices, {nf} faces.
# Source: Stanford University Computer Graphics Laboratory, the Stanford 3D Scanning
# Repository (graphics.stanford.edu/data/3Dscanrep/; Turk & Levoy 1994, Cyberware scanner,
# zipper reconstruction). Terms: see bunny-LICENSE.txt beside this file.
# +Y up, metres; no normals stored (computed from the faces, which wind outward).
"""


def make(source: Path) -> str:
    """The text of the packaged bunny made from ``source``."""
    import fast_simplification
    import trimesh

    m = trimesh.load(source, process=True)
    reduction = 1.0 - TARGET_FACES / len(m.faces)
    v, f = fast_simplification.simplify(np.asarray(m.vertices, np.float64),
                                        np.asarray(m.faces, np.int64),
                                        target_reduction=max(reduction, 0.0))
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
    source = Path(sys.argv[1]) if len(sys.argv) > 1 else data / "meshes" / "bunny.obj"
    text = make(source)
    TARGET.parent.mkdir(parents=True, exist_ok=True)
    TARGET.write_text(text)
    print(f"wrote {TARGET} ({len(text.encode())} bytes)")


if __name__ == "__main__":
    main()

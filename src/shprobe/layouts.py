"""Image parameterisations of the sphere (lat-long, angular map, mirror ball, cube maps): every
direction convention of shprobe in one module.
"""

from __future__ import annotations

"""SH conventions: shprobe's own, and converters to/from Condon–Shortley phase and 4π
normalisation.
"""

from __future__ import annotations

"""Image I/O through OpenImageIO: HDR/EXR/PFM/TIFF/PNG/JPEG in, EXR/HDR/PFM/PNG out."""

from __future__ import annotations

"""Export and import of coefficients: shaders (GLSL/HLSL/WGSL), JSON, three.js, glTF, cmgen,
Condon–Shortley.
"""

from __future__ import annotations

"""Lighting design (R&H 2001 §3.3): editing coefficients, analytic lights, windowing and the non-
negativity certificate.
"""

from __future__ import annotations

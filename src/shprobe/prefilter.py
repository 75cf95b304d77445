"""Prefiltering (R&H 2001 eq. 10), irradiance (eq. 7, 11–13), the brute-force reference and the
error report.
"""

from __future__ import annotations

"""Layer 1, SH maths: the real SH basis of any degree, zonal functions, Wigner rotation and
the converters to other conventions. Imports nothing else of shprobe but ``errors``."""

from .basis import sh_basis, sh_basis_numpy, sh_basis_scipy
from .indexing import (
    LMAX_LIMIT,
    check_lmax,
    degrees,
    lmax_of,
    num_coeffs,
    recurrence_tables,
    sh_index,
    sh_lm,
)

__all__ = [
    "LMAX_LIMIT",
    "check_lmax",
    "degrees",
    "lmax_of",
    "num_coeffs",
    "recurrence_tables",
    "sh_basis",
    "sh_basis_numpy",
    "sh_basis_scipy",
    "sh_index",
    "sh_lm",
]

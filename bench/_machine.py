"""What every benchmark prints about the machine it ran on (imported by the bench scripts,
which run as ``python bench/<name>.py`` so this folder is on sys.path)."""

from __future__ import annotations

import os
import platform


def machine() -> str:
    """CPU model, cores, Python, numpy, numba, 1/5/15-min load average."""
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    import numpy as np

    try:
        import numba
    except ImportError:  # pragma: no cover
        numba = None
    load = os.getloadavg() if hasattr(os, "getloadavg") else (float("nan"),) * 3
    return (f"{cpu}, {os.cpu_count()} cores, Python {platform.python_version()}, numpy "
            f"{np.__version__}" + (f", numba {numba.__version__}" if numba else "")
            + f", load average {load[0]:.2f} / {load[1]:.2f} / {load[2]:.2f} (1 / 5 / 15 min)"
            " at start")

"""The Node packages of tests/consumers/ (pinned by its package-lock.json), installed by the
tests themselves where npm exists, so the README's test command needs no set-up step of its
own: ``npm ci`` once per lock (a marker file holds the lock's sha256, as .ci/run writes it),
under a file lock shared by xdist workers. Where npm is absent the callers skip, saying so."""

from __future__ import annotations

import fcntl
import hashlib
import shutil
import subprocess
import tempfile
from pathlib import Path

CONSUMERS = Path(__file__).resolve().parents[1] / "consumers"


def ensure_npm_packages(folder: Path = CONSUMERS) -> bool:
    """Run ``npm ci`` in ``folder`` unless its node_modules already match the lock; True when
    the packages are installed."""
    if shutil.which("npm") is None:
        return False
    lock_sum = hashlib.sha256((folder / "package-lock.json").read_bytes()).hexdigest()
    marker = folder / "node_modules" / ".shprobe-lock.sha256"
    key = hashlib.sha256(str(folder.resolve()).encode()).hexdigest()[:16]
    with open(Path(tempfile.gettempdir()) / f"shprobe-npm-ci-{key}.lock", "w") as f:
        fcntl.flock(f, fcntl.LOCK_EX)
        if marker.is_file() and marker.read_text().strip() == lock_sum:
            return True
        r = subprocess.run(["npm", "ci", "--no-audit", "--no-fund", "--loglevel=error"],
                           cwd=folder, capture_output=True, text=True, timeout=900)
        if r.returncode != 0:
            return False
        marker.write_text(lock_sum + "\n")
        return True

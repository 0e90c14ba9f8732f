"""Matplotlib set-up and atomic, byte-reproducible PNG writes, shared by every stage's figures."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import matplotlib

from .files import umask

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

# fixed metadata keeps PNGs byte-reproducible
METADATA = {"Software": "netgen"}


def save(fig, path: Path, dpi: int = 110) -> Path:
    """Write a figure atomically (temp file + rename) and close it."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp.png", dir=path.parent)
    os.close(fd)
    try:
        fig.savefig(tmp, dpi=dpi, metadata=METADATA)
        os.chmod(tmp, 0o666 & ~umask())  # mkstemp's 0600 is not the user's choice
        os.replace(tmp, path)
    finally:
        plt.close(fig)
        if os.path.exists(tmp):
            os.unlink(tmp)
    return path

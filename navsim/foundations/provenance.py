"""What a run records about itself: versions, git revision, time, command line."""

from __future__ import annotations

import functools
import platform
import subprocess
import sys
from datetime import datetime, timezone
from importlib import metadata
from pathlib import Path

from navsim.version import __version__

PACKAGES = ("numpy", "scipy", "numba", "jsbsim", "matplotlib", "pyyaml", "tqdm", "pyulog", "xarray")


def git_revision() -> str | None:
    """The git commit of the navsim checkout this package is imported from (with ``-dirty`` if
    its tracked files are modified); ``None`` for an installed package (a wheel in
    site-packages, even one inside some other repository or a virtual environment within the
    checkout), where git is missing, or where it fails."""
    root = Path(__file__).resolve().parents[2]          # the folder holding the navsim package
    try:
        rev = subprocess.run(["git", "-C", str(root), "rev-parse", "--show-toplevel", "HEAD"],
                             capture_output=True, text=True, timeout=5)
        lines = rev.stdout.split()
        if rev.returncode != 0 or len(lines) != 2 or Path(lines[0]).resolve() != root:
            return None
        dirty = subprocess.run(["git", "-C", str(root), "status", "--porcelain", "--untracked-files=no"],
                               capture_output=True, text=True, timeout=5).stdout.strip()
        return lines[1] + ("-dirty" if dirty else "")
    except (OSError, subprocess.SubprocessError):
        return None


@functools.lru_cache(maxsize=1)
def _versions() -> dict:
    """navsim's, Python's and :data:`PACKAGES`' versions (read once a process: 1 ms each)."""
    versions = {"navsim": __version__, "python": platform.python_version()}
    for name in PACKAGES:
        try:
            versions[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            versions[name] = None
    return versions


def provenance() -> dict:
    return {"versions": dict(_versions()), "git_revision": git_revision(),
            "utc": datetime.now(timezone.utc).isoformat(timespec="seconds"),
            "command": " ".join(sys.argv), "platform": platform.platform()}

"""Slim the container's virtual environment for its runtime stage (docker/Dockerfile).

* Identical files (wheels ship ``libX.so``, ``libX.so.0`` and ``libX.so.0.3`` as three
  copies, casadi's plugins for one) become symlinks to one of them: ~200 MB.
* What only a build or a test uses goes: static libraries (``*.a``), C headers
  (``include/``), the packages' own test suites, pip and setuptools.

Usage: python slim_venv.py VENV
"""

from __future__ import annotations

import hashlib
import os
import shutil
import sys
from pathlib import Path

MIN_DEDUP_BYTES = 64 * 1024  # [B] smaller files are not worth a symlink
REMOVED_DIRS = ("include",)  # C headers: the runtime compiles nothing
TEST_DIRS = ("tests",)
REMOVED_PACKAGES = ("pip", "setuptools", "_distutils_hack")


def _digest(path: Path) -> str:
    h = hashlib.sha256()
    with path.open("rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def deduplicate(root: Path) -> int:
    """Replace each identical copy of a file by a relative symlink; bytes saved."""
    first: dict[tuple[int, str], Path] = {}
    saved = 0
    for path in sorted(p for p in root.rglob("*") if p.is_file() and not p.is_symlink()):
        size = path.stat().st_size
        if size < MIN_DEDUP_BYTES:
            continue
        key = (size, _digest(path))
        if key not in first:
            first[key] = path
            continue
        target = os.path.relpath(first[key], path.parent)
        path.unlink()
        path.symlink_to(target)
        saved += size
    return saved


def remove_build_and_test_files(venv: Path) -> int:
    removed = 0
    site = next(venv.glob("lib/python3*/site-packages"))
    doomed = [venv / name for name in REMOVED_DIRS]
    doomed += [p for p in site.rglob("*") if p.is_dir() and p.name in REMOVED_DIRS + TEST_DIRS]
    doomed += [site / name for name in REMOVED_PACKAGES]
    doomed += [p for p in site.glob("*.dist-info") if p.name.split("-")[0] in REMOVED_PACKAGES]
    doomed += [p for p in site.rglob("*.a") if p.is_file()]
    for path in doomed:
        if not path.exists():
            continue
        if path.is_dir():
            removed += sum(f.stat().st_size for f in path.rglob("*") if f.is_file())
            shutil.rmtree(path)
        else:
            removed += path.stat().st_size
            path.unlink()
    for script in ("pip", "pip3", "pip3.11"):
        (venv / "bin" / script).unlink(missing_ok=True)
    return removed


def main(venv: Path) -> int:
    removed = remove_build_and_test_files(venv)
    saved = deduplicate(venv)
    print(f"{venv}: removed {removed / 1e6:.0f} MB, deduplicated {saved / 1e6:.0f} MB")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(Path(sys.argv[1])))

"""The model cache's bound: what it holds, entry by entry, and least-recently-used pruning.

An entry is what one build leaves: a generated module (a model or an env's fused step) with
numba's files for it, or numba's files for one task function a user wrote (kept in the
cache's `functions/` folder, `dynamics.cache.cache_function`). Using an entry marks it used
(the module's or the index file's modification time is set to now), so every edit of a
user's module, which makes a new entry, leaves the old one to age out.

The bound is `LIMIT_BYTES` (or `$LAGRANGE_GYM_CACHE_LIMIT`, e.g. ``500M``, ``2G``): after a
build that takes the cache past it, the least recently used entries are removed until it
holds at most `TARGET` of it. `python -m dynamics cache list` shows the entries, `prune`
removes by size or age. Pruning is safe beside running processes: one process prunes at a
time (a lock), an entry used in the last `GRACE_S` seconds is never removed, a module is
renamed away before its numba files go (a loader that finds it missing rebuilds it), and
numba treats a vanished file of its own as a cache miss.
"""

from __future__ import annotations

import contextlib
import os
import re
import time
from dataclasses import dataclass
from pathlib import Path

LIMIT_ENV = "LAGRANGE_GYM_CACHE_LIMIT"
LIMIT_BYTES = 1 << 30
"""The default bound: 1 GiB (a model with its machine code takes 0.1 to 2 MiB; the built-in
models and fused steps, about 20 MiB)."""
TARGET = 0.8
"""Automatic pruning stops at this share of the bound, so it does not run at every build."""
GRACE_S = 3600.0
"""An entry used within this many seconds is kept whatever the bound (a running process may
still read its numba files)."""
FUNCTIONS = "functions"
"""The cache's folder for numba's files of the task functions users write."""
_UNITS = {"": 1, "K": 1 << 10, "M": 1 << 20, "G": 1 << 30, "T": 1 << 40}


@dataclass(frozen=True)
class Entry:
    """One build's files: `name` to show, `files` (the first marks its use), their bytes."""

    name: str
    files: tuple[Path, ...]
    size: int
    last_used: float


def parse_size(text: str, option: str = LIMIT_ENV) -> int:
    """Bytes of '500M', '2G', '1.5G' or a plain number; ValueError naming `option`."""
    found = re.fullmatch(r"\s*(\d+(?:\.\d+)?)\s*([KMGT]?)i?B?\s*", str(text), re.IGNORECASE)
    if not found or float(found[1]) <= 0:
        raise ValueError(
            f"{option} must be a size such as 500M or 2G (bytes, K, M, G, T), got {text!r}."
        )
    return int(float(found[1]) * _UNITS[found[2].upper()])


def parse_age(text: str, option: str = "--older-than") -> float:
    """Seconds of '30d', '12h', '90m', '45s'; ValueError naming `option`."""
    found = re.fullmatch(r"\s*(\d+(?:\.\d+)?)\s*([dhms])\s*", str(text))
    if not found:
        raise ValueError(f"{option} must be an age such as 30d, 12h, 90m or 45s, got {text!r}.")
    return float(found[1]) * {"d": 86400, "h": 3600, "m": 60, "s": 1}[found[2]]


def limit() -> int:
    """The bound in bytes: `$LAGRANGE_GYM_CACHE_LIMIT` if set, else `LIMIT_BYTES`."""
    text = os.environ.get(LIMIT_ENV)
    return LIMIT_BYTES if not text else parse_size(text)


def entries(root: Path) -> list[Entry]:
    """The cache's entries, least recently used first."""
    found = []
    numba_dir = root / "__pycache__"
    for module in root.glob("*.py"):
        if module.name.startswith("."):  # a write or a removal in flight
            continue
        files = [module, *numba_dir.glob(f"{glob_escape(module.stem)}.*")]
        files.append(root / f".{module.name}.lock")  # (dynamics.cache._lock's file)
        found.append(_entry(module.name, files))
    for index in (root / FUNCTIONS).glob("*/*.nbi"):
        base = index.name[: -len(".nbi")]
        files = [index, *index.parent.glob(f"{glob_escape(base)}.*.nbc")]
        found.append(_entry(f"{FUNCTIONS}/{index.parent.name}/{base}", files))
    return sorted((e for e in found if e is not None), key=lambda e: e.last_used)


def glob_escape(text: str) -> str:
    return re.sub(r"([*?[])", r"[\1]", text)


def _entry(name: str, files: list[Path]) -> Entry | None:
    sizes, first = 0, None
    for f in files:
        try:
            st = f.stat()
        except OSError:  # removed meanwhile
            if f is files[0]:
                return None
            continue
        sizes += st.st_size
        first = st.st_mtime if first is None else first
    return Entry(name, tuple(files), sizes, first)


def mark_used(path: Path) -> None:
    """Record a use of the entry whose first file is `path` (its modification time)."""
    with contextlib.suppress(OSError):
        os.utime(path)


def prune(
    root: Path,
    max_bytes: int | None = None,
    older_than: float | None = None,
    grace: float = GRACE_S,
    now: float | None = None,
) -> list[Entry] | None:
    """Remove the least recently used entries until the cache holds at most `max_bytes`,
    and every entry unused for `older_than` seconds; never one used within `grace`
    seconds. Returns the removed entries, or None when another process is pruning."""
    now = time.time() if now is None else now
    with _pruning(root) as held:
        if not held:
            return None
        listed = entries(root)
        total = sum(e.size for e in listed)
        removed = []
        for e in listed:
            if now - e.last_used < grace:
                break  # the rest were used later still
            old = older_than is not None and now - e.last_used > older_than
            if old or (max_bytes is not None and total > max_bytes):
                _remove(e)
                total -= e.size
                removed.append(e)
        return removed


def keep_bounded(root: Path) -> None:
    """After a build: prune to `TARGET` of the bound when the cache is past it."""
    try:
        bound = limit()
    except ValueError as exc:  # a bad bound: say so once per build, keep everything
        import warnings

        warnings.warn(f"{exc} The cache is not pruned.", RuntimeWarning, stacklevel=3)
        return
    if sum(e.size for e in entries(root)) > bound:
        prune(root, max_bytes=int(TARGET * bound))


def _remove(entry: Entry) -> None:
    """The entry's first file renamed away first (a loader then rebuilds, never reads half
    an entry), then every file removed."""
    first, rest = entry.files[0], entry.files[1:]
    gone = first.with_name(f".pruned-{os.getpid()}-{first.name}")
    try:
        os.replace(first, gone)
    except OSError:
        return
    for f in (*rest, gone):
        with contextlib.suppress(OSError):
            f.unlink()


@contextlib.contextmanager
def _pruning(root: Path):
    """Yield True while holding the cache's prune lock, False if another process has it."""
    try:
        import fcntl
    except ImportError:  # pragma: no cover - not POSIX
        yield True
        return
    try:
        fd = os.open(root / ".prune.lock", os.O_RDWR | os.O_CREAT, 0o600)
    except OSError:
        yield False  # a read-only cache: nothing to prune
        return
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        os.close(fd)
        yield False
        return
    try:
        yield True
    finally:
        os.close(fd)

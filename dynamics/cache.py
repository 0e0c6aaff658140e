"""On-disk cache of generated model modules (and of the environments' fused steps,
`envs/fused.py`, which use the same mechanism).

Each compiled model is one Python file named by a key that hashes everything its code depends
on; numba keeps its machine code beside it (``__pycache__``). The file's first line records
its key and the sha256 of the rest, and both are checked before the file is run. Files are
written to a temporary name and renamed, so readers never see a partial file; a process that
must build a missing model holds a lock (``flock``, released by the system if the process
dies) while the others wait for its file instead of deriving it too. A file that fails a check
or fails to load, or whose numba cache files are unreadable, is removed and rebuilt.

The directory is ``$LAGRANGE_GYM_CACHE`` if set, else ``$XDG_CACHE_HOME/lagrange-gym`` (or
``~/.cache/lagrange-gym``), created private to its user (0o700). If it cannot be written,
models are built in a private temporary directory removed at exit, with one warning.
"""

from __future__ import annotations

import atexit
import hashlib
import os
import pickle
import shutil
import sys
import tempfile
import time
import warnings
from collections.abc import Callable
from pathlib import Path
from types import ModuleType

from .files import write_atomic

try:
    import fcntl
except ImportError:  # not POSIX: concurrent builds each derive (still correct)
    fcntl = None

ENV_VAR = "LAGRANGE_GYM_CACHE"
LOCK_TIMEOUT = 600.0
"""Seconds to wait for another process's build before building anyway (a cold derivation
takes well under a minute)."""
_HEADER = "# lagrange-gym "
_loaded: dict[str, ModuleType] = {}
_fallback: list[Path] = []


def cache_dir() -> Path:
    """The cache directory (created, private to its user, if missing)."""
    root = os.environ.get(ENV_VAR)
    if root:
        path = Path(root)
    else:
        base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
        path = Path(base) / "lagrange-gym"
    try:
        path.mkdir(mode=0o700, parents=True, exist_ok=True)
    except OSError as exc:
        raise OSError(
            f"Cannot create the model cache {path}; set {ENV_VAR} to a writable directory."
        ) from exc
    return path


def _private_dir(reason: Exception) -> Path:
    """A temporary directory for this process's models, made (with a warning) on first use."""
    if not _fallback:
        path = Path(tempfile.mkdtemp(prefix="lagrange-gym-"))  # 0o700
        atexit.register(shutil.rmtree, path, ignore_errors=True)
        _fallback.append(path)
        warnings.warn(
            f"The model cache is not writable ({reason}); compiled models go to a temporary "
            f"directory for this process only. Set {ENV_VAR} to a writable directory to keep "
            "them.",
            RuntimeWarning,
            stacklevel=4,
        )
    return _fallback[0]


def _digest(body: str) -> str:
    return hashlib.sha256(body.encode("utf-8")).hexdigest()


def stamped(key: str, body: str) -> str:
    """The file text for `body`: a first line with the key and the body's sha256."""
    return f"{_HEADER}{key} sha256={_digest(body)}\n{body}"


def body_of(text: str, key: str) -> str | None:
    """The body of a stamped file text if its key and hash are right, else None."""
    header, _, body = text.partition("\n")
    return body if header == f"{_HEADER}{key} sha256={_digest(body)}" else None


def _file_name(name: str, key: str) -> str:
    return f"{name}_{key[:20]}.py"


def _discard(path: Path, module_too: bool = True) -> None:
    """Remove a damaged module (if `module_too`) and its numba cache files."""
    numba_files = (path.parent / "__pycache__").glob(f"{path.stem}.*")
    for f in [path, *numba_files] if module_too else numba_files:
        try:
            f.unlink()
        except OSError:
            pass


def _numba_files_readable(path: Path) -> bool:
    """Whether numba's index and data files for the loaded module at `path` unpickle (numba
    itself would crash on the first call of a kernel whose file is truncated or garbage)."""
    folder = path.parent / "__pycache__"
    try:
        for index in folder.glob(f"{path.stem}.*.nbi"):
            with open(index, "rb") as fh:
                pickle.load(fh)  # numba's format version
                _, overloads = pickle.loads(fh.read())
            for data in overloads.values():
                pickle.loads((folder / data).read_bytes())
    except FileNotFoundError:
        return True  # removed by a concurrent rebuild: numba recompiles
    except Exception:
        return False
    return True


def _load_file(path: Path, key: str) -> ModuleType | None:
    """The verified module at `path`, or None (a damaged file is discarded)."""
    try:
        text = path.read_bytes().decode("utf-8")
    except FileNotFoundError:
        return None
    except (OSError, UnicodeDecodeError):
        _discard(path)
        return None
    if body_of(text, key) is None:
        _discard(path)
        return None
    module_name = f"lagrange_gym_generated.{path.stem}"
    module = ModuleType(module_name)
    module.__file__ = str(path)
    sys.modules[module_name] = module
    try:
        exec(compile(text, str(path), "exec"), module.__dict__)
        if module.KEY != key:
            raise ValueError("key mismatch")
    except Exception:
        del sys.modules[module_name]
        _discard(path)
        return None
    if not _numba_files_readable(path):  # the module is fine: numba recompiles its kernels
        _discard(path, module_too=False)
    return module


def load(name: str, key: str, body: str | None = None) -> ModuleType | None:
    """The generated module for (name, key): from memory, from disk, or written from `body`.

    Returns None when it is not cached (or damaged) and no body is given.
    """
    if key in _loaded:
        return _loaded[key]
    try:
        path = cache_dir() / _file_name(name, key)
    except OSError as exc:
        path = _private_dir(exc) / _file_name(name, key)
    module = _load_file(path, key)
    if module is None and body is not None:
        text = stamped(key, body)
        try:
            write_atomic(path, text)
        except OSError as exc:
            path = _private_dir(exc) / path.name
            write_atomic(path, text)
        module = _load_file(path, key)
        if module is None:
            raise RuntimeError(f"The generated module {path} does not load.")
    if module is not None:
        _loaded[key] = module
    return module


def load_or_build(name: str, key: str, build: Callable[[], str]) -> ModuleType:
    """The module for (name, key), calling `build()` for its body only if no process has
    it: concurrent callers wait on one lock while its holder builds."""
    module = load(name, key)
    if module is not None:
        return module
    with _lock(name, key):
        module = load(name, key)  # built by another process while we waited
        if module is None:
            module = load(name, key, build())
    return module


class _lock:
    """An exclusive flock on the model's lock file; no-op where that cannot be had."""

    def __init__(self, name: str, key: str):
        self.fd = None
        if fcntl is None:
            return
        try:
            path = cache_dir() / f".{_file_name(name, key)}.lock"
            self.fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o600)
        except OSError:
            self.fd = None  # read-only cache: this process builds in private

    def __enter__(self):
        if self.fd is None:
            return self
        deadline = time.monotonic() + LOCK_TIMEOUT
        while True:
            try:
                fcntl.flock(self.fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                return self
            except BlockingIOError:
                if time.monotonic() > deadline:
                    msg = "Gave up waiting for another process's model build; building too."
                    warnings.warn(msg, RuntimeWarning, stacklevel=2)
                    return self
                time.sleep(0.05)

    def __exit__(self, *exc):
        if self.fd is not None:
            os.close(self.fd)  # releases the lock

"""On-disk cache of generated model modules.

Each compiled model is one Python file named by a key that hashes everything its code depends
on; numba keeps its machine code beside it (``__pycache__``). Files are written to a temporary
name and renamed, so processes compiling the same model at once never see a partial file.
The directory is ``$LAGRANGE_GYM_CACHE`` if set, else ``$XDG_CACHE_HOME/lagrange-gym`` (or
``~/.cache/lagrange-gym``).
"""

from __future__ import annotations

import importlib.util
import os
import sys
import tempfile
from pathlib import Path
from types import ModuleType

ENV_VAR = "LAGRANGE_GYM_CACHE"
_loaded: dict[str, ModuleType] = {}
_UMASK = os.umask(0)
os.umask(_UMASK)


def cache_dir() -> Path:
    """The cache directory (created if missing)."""
    root = os.environ.get(ENV_VAR)
    if root:
        path = Path(root)
    else:
        base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
        path = Path(base) / "lagrange-gym"
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OSError(
            f"Cannot create the model cache {path}; set {ENV_VAR} to a writable directory."
        ) from exc
    return path


def _path(name: str, key: str) -> Path:
    return cache_dir() / f"{name}_{key[:20]}.py"


def write_atomic(path: Path, data: str | bytes) -> None:
    """Write `data` (text as UTF-8, or bytes) to `path` through a temporary file in the same
    directory and a rename, so readers never see a partial file."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data.encode("utf-8") if isinstance(data, str) else data)
            fh.flush()
            os.fsync(fh.fileno())
        os.chmod(tmp, 0o666 & ~_UMASK)  # mkstemp makes 0600; give the file normal permissions
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def load(name: str, key: str, source: str | None = None) -> ModuleType | None:
    """The generated module for (name, key): from memory, from disk, or written from `source`.

    Returns None when it is not cached and no source is given.
    """
    if key in _loaded:
        return _loaded[key]
    path = _path(name, key)
    if not path.exists():
        if source is None:
            return None
        write_atomic(path, source)
    module_name = f"lagrange_gym_generated.{path.stem}"
    spec = importlib.util.spec_from_file_location(module_name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[module_name] = module
    spec.loader.exec_module(module)
    if getattr(module, "KEY", None) != key:
        del sys.modules[module_name]
        if source is None:
            return None
        write_atomic(path, source)  # a damaged or colliding file: rebuild it
        return load(name, key, source)
    _loaded[key] = module
    return module

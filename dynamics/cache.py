"""On-disk cache of generated model modules (and of the environments' fused steps,
`envs/fused.py`, which use the same mechanism).

Each compiled model is one Python file named by a key that hashes everything its code depends
on; numba keeps its machine code beside it (``__pycache__``), and that of the task functions
users write in ``functions/`` (`function_cache`). The cache is bounded: least recently used
entries are pruned past a stated size (`dynamics.pruning`; `python -m dynamics cache`). The
file's first line records its key and the sha256 of the rest, and both are checked before the
file is run: that finds
damage, not tampering (anyone who can write the file can write the line too). Where the loader
knows the exact text it expects (the fused steps, a pickled model's own source) it compares
the whole file with it. Files are written to a temporary name and renamed, so readers never
see a partial file; a process that must build a missing model holds a lock (``flock``,
released by the system if the process dies) while the others wait for its file instead of
deriving it too. A file that fails a check or fails to load, or whose numba cache files are
not well-formed pickles (checked by parsing, never by unpickling), is removed and rebuilt.
Only regular files of at most `MAX_FILE_BYTES` are read (a FIFO or a link to a device is
discarded, not opened for reading).

What is in the cache runs as code: the modules when loaded, numba's files when numba
unpickles them. So the directory must be writable by its user alone. It is
``$LAGRANGE_GYM_CACHE`` if set, else ``$XDG_CACHE_HOME/lagrange-gym`` (or
``~/.cache/lagrange-gym``), created private to its user (0o700), and so is numba's
``__pycache__`` in it (made here before numba would make it with the process umask). One that
another user owns, or that another user may write (others' write permission, or the group's
where the group has a member besides this user: under umask 002 with a user's private group,
group-writable folders are still the user's alone) is not used: models are then built in a
private temporary directory removed at exit, with one warning saying why (as when it cannot
be written).
"""

from __future__ import annotations

import atexit
import functools
import hashlib
import io
import os
import pickletools
import shutil
import stat
import sys
import tempfile
import time
import warnings
from collections.abc import Callable
from pathlib import Path
from types import ModuleType

from . import pruning
from .files import write_atomic

try:
    import fcntl
except ImportError:  # not POSIX: concurrent builds each derive (still correct)
    fcntl = None

ENV_VAR = "LAGRANGE_GYM_CACHE"
LOCK_TIMEOUT = 600.0
"""Seconds to wait for another process's build before building anyway (a cold derivation
takes well under a minute)."""
MAX_FILE_BYTES = 64 * 2**20
"""The largest cache file read (a generated module is well under 1 MiB; numba's files too)."""
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
    for folder in (path, path / "__pycache__"):
        if folder.name == "__pycache__":  # numba would make it with the umask (0o775 for 002)
            try:
                folder.mkdir(mode=0o700, exist_ok=True)
            except OSError:
                pass  # a read-only cache: checked below all the same
        problem = _unsafe(folder)
        if problem:
            raise UnsafeCacheError(
                f"{folder} {problem}, so what is in it cannot be trusted to run; make it "
                f"private (chmod 700) or set {ENV_VAR} to a directory of your own"
            )
    return path


class UnsafeCacheError(OSError):
    """The cache directory is one that other users can write."""


def _unsafe(folder: Path) -> str | None:
    """Why `folder` (if it exists; a link is followed) cannot be trusted: another owner, or
    write permission for another user (others, or a group with a member besides this user)."""
    try:
        st = folder.stat()
    except FileNotFoundError:
        return None
    if st.st_uid != os.geteuid():
        return f"is owned by uid {st.st_uid}, not by this user (uid {os.geteuid()})"
    return _writable_by_others(folder, st)


def _writable_by_others(path: Path, st=None) -> str | None:
    """Why another user may write `path` (others' write permission, or the group's where
    the group has a member besides this user), or None."""
    st = st or path.stat()
    mode = stat.S_IMODE(st.st_mode)
    if mode & stat.S_IWOTH:
        return f"is writable by others (mode {mode:04o})"
    if mode & stat.S_IWGRP:
        others = group_members_besides_me(st.st_gid)
        if others:
            return (
                f"is writable by others: by its group (mode {mode:04o}), whose members include "
                f"{', '.join(others[:3])}"
            )
    return None


def group_members_besides_me(gid: int) -> list[str]:
    """The users other than this one who belong to group `gid` (its listed members and the
    users whose primary group it is); ['unknown users'] where that cannot be told."""
    try:
        import grp
        import pwd
    except ImportError:  # not POSIX
        return ["unknown users"]
    me = os.geteuid()
    try:
        group = grp.getgrgid(gid)
        names = set(group.gr_mem) | {u.pw_name for u in pwd.getpwall() if u.pw_gid == gid}
        mine = {u.pw_name for u in pwd.getpwall() if u.pw_uid == me}
    except (KeyError, OSError):
        return ["unknown users"]
    return sorted(names - mine)


def _private_dir(reason: Exception) -> Path:
    """A temporary directory for this process's models, made (with a warning) on first use."""
    if not _fallback:
        path = Path(tempfile.mkdtemp(prefix="lagrange-gym-"))  # 0o700
        atexit.register(shutil.rmtree, path, ignore_errors=True)
        _fallback.append(path)
        what = "is not used" if isinstance(reason, UnsafeCacheError) else "is not writable"
        warnings.warn(
            f"The model cache {what} ({reason}); compiled models go to a temporary "
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


def read_bytes(path: Path) -> bytes:
    """The bytes of the regular file at `path`, at most `MAX_FILE_BYTES` of them.

    Raises FileNotFoundError if it is missing and OSError if it is not a regular file (a
    FIFO, a device, a directory; opened without blocking) or is larger."""
    fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            raise OSError(f"{path} is not a regular file")
        if st.st_size > MAX_FILE_BYTES:
            raise OSError(f"{path} is larger than {MAX_FILE_BYTES} bytes")
        with os.fdopen(fd, "rb", closefd=False) as fh:
            data = fh.read(MAX_FILE_BYTES + 1)
    finally:
        os.close(fd)
    if len(data) > MAX_FILE_BYTES:
        raise OSError(f"{path} is larger than {MAX_FILE_BYTES} bytes")
    return data


def _well_formed_pickles(data: bytes, count: int) -> bool:
    """Whether `data` is exactly `count` complete pickle streams, parsed without running any
    of it (`pickletools.genops` reads opcodes; nothing is constructed)."""
    stream = io.BytesIO(data)
    try:
        for _ in range(count):
            for _ in pickletools.genops(stream):
                pass
    except Exception:
        return False
    return stream.tell() == len(data)


def _numba_files_sound(path: Path) -> bool:
    """Whether numba's index and data files for the module at `path` are regular files of
    well-formed pickles (numba itself would crash on the first call of a kernel whose file is
    truncated or garbage, and hang on a FIFO). An index is two pickles (numba's format
    version, then its entries), a data file one."""
    folder = path.parent / "__pycache__"
    try:
        for f in folder.glob(f"{path.stem}.*.nb[ic]"):
            count = 2 if f.suffix == ".nbi" else 1
            if not _well_formed_pickles(read_bytes(f), count):
                return False
    except FileNotFoundError:
        return True  # removed by a concurrent rebuild: numba recompiles
    except OSError:
        return False
    return True


def _load_file(path: Path, key: str, expected: str | None = None) -> ModuleType | None:
    """The verified module at `path`, or None (a damaged file is discarded). With
    `expected`, the file must hold exactly that text."""
    try:
        if _writable_by_others(path):  # a file another user may have written: not run
            _discard(path)
            return None
        text = read_bytes(path).decode("utf-8")
    except FileNotFoundError:
        return None
    except (OSError, UnicodeDecodeError):
        _discard(path)
        return None
    if body_of(text, key) is None or (expected is not None and text != expected):
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
    if not _numba_files_sound(path):  # the module is fine: numba recompiles its kernels
        _discard(path, module_too=False)
    return module


def load(name: str, key: str, body: str | None = None) -> ModuleType | None:
    """The generated module for (name, key): from memory, from disk, or written from `body`.

    With `body`, a file on disk is used only if it holds exactly that body (else it is
    rewritten). Returns None when it is not cached (or damaged) and no body is given.
    """
    if key in _loaded:
        return _loaded[key]
    try:
        path = cache_dir() / _file_name(name, key)
    except OSError as exc:
        path = _private_dir(exc) / _file_name(name, key)
    text = None if body is None else stamped(key, body)
    module = _load_file(path, key, text)
    if module is None and text is not None:
        try:
            write_atomic(path, text)
        except OSError as exc:
            path = _private_dir(exc) / path.name
            write_atomic(path, text)
        module = _load_file(path, key, text)
        if module is None:
            raise RuntimeError(f"The generated module {path} does not load.")
        pruning.keep_bounded(path.parent)  # a new entry: the cache stays within its bound
    if module is not None:
        pruning.mark_used(path)
        _loaded[key] = module
    return module


def cache_function(dispatcher, fn) -> None:
    """Give `dispatcher` (numba's, for `fn`, a task function a user wrote, before its first
    compile) an on-disk cache inside this cache (`pruning.FUNCTIONS`, bounded with the rest)
    instead of numba's default, the `__pycache__` beside the user's source: numba's own cache
    class with a locator of its documented kind (`numba.core.caching`), set as
    `njit(cache=True)` sets the default one (numba has no public argument for it), and kept
    true to helpers edited in other files (`keep_numba_cache_true`). OSError where the cache
    cannot be used (the caller then compiles without a disk cache)."""
    root = cache_dir() / pruning.FUNCTIONS
    root.mkdir(mode=0o700, exist_ok=True)
    cache = _function_cache_class()(fn)
    index = Path(cache.cache_path) / f"{cache._impl.filename_base}.nbi"
    if not _numba_index_sound(index):
        cache.flush()  # a damaged index: numba would crash on it; recompile instead
    pruning.mark_used(index)
    dispatcher._cache = cache
    keep_numba_cache_true(dispatcher, fn)


def _numba_index_sound(index: Path) -> bool:
    """Whether the index at `index` and its data files are well-formed pickles (or absent)."""
    try:
        if index.exists() and not _well_formed_pickles(read_bytes(index), 2):
            return False
        for data in index.parent.glob(f"{pruning.glob_escape(index.stem)}.*.nbc"):
            if not _well_formed_pickles(read_bytes(data), 1):
                return False
    except OSError:
        return False
    return True


@functools.cache
def _function_cache_class():
    from numba.core.caching import (
        CompileResultCacheImpl,
        FunctionCache,
        UserProvidedCacheLocator,
    )

    class Locator(UserProvidedCacheLocator):
        """numba's locator for a cache folder of one's own (as NUMBA_CACHE_DIR gives), here
        this cache's `functions/`, for these functions only."""

        def __init__(self, py_func, py_file):
            super().__init__(py_func, py_file)
            root = cache_dir() / pruning.FUNCTIONS
            self._cache_path = str(root / self.get_suitable_cache_subpath(py_file))

        @classmethod
        def from_function(cls, py_func, py_file):  # (the parent's asks for NUMBA_CACHE_DIR)
            return super(UserProvidedCacheLocator, cls).from_function(py_func, py_file)

    class Impl(CompileResultCacheImpl):
        _locator_classes = [Locator]

    class Cache(FunctionCache):
        _impl_class = Impl

    return Cache


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


def foreign_code(fn) -> str | None:
    """sha256 of the code of every Python function `fn` reaches (through globals, closures,
    defaults, `module.attr`) that is defined in another file than `fn`, or None when it
    reaches none. Library functions (numpy, math, numba) are not followed."""
    import types

    fn = _function(fn)
    if fn is None:
        return None
    home, seen, todo = fn.__code__.co_filename, set(), [fn]
    h, foreign = hashlib.sha256(), False
    while todo:
        f = _function(todo.pop())
        if f is None or id(f) in seen:
            continue
        seen.add(id(f))
        if f.__code__.co_filename != home:
            foreign = True
            h.update(f"{f.__code__.co_filename}:{f.__qualname__}".encode())
            _hash_code(h, f.__code__)
        names = _code_names(f.__code__)
        reached = [f.__globals__.get(n) for n in names]
        reached += [c.cell_contents for c in f.__closure__ or () if _assigned(c)]
        reached += list(f.__defaults__ or ())
        for obj in list(reached):
            if isinstance(obj, types.ModuleType) and not _library_module(obj):
                reached += [getattr(obj, n, None) for n in names]
        todo += [o for o in reached if _function(o) is not None]
    return h.hexdigest() if foreign else None


def keep_numba_cache_true(dispatcher, fn) -> None:
    """numba keys a function's cached machine code on its own source file only, though that
    code includes every jitted helper it calls: after an edit of a helper in another file,
    the cache would serve the old helper. Here the code of those helpers (`foreign_code`) is
    kept beside the model cache, and numba's cache of `dispatcher` (compiled from `fn`,
    before its first call) is emptied when it changed, so numba compiles afresh."""
    digest = foreign_code(fn)
    if digest is None:
        return
    code = fn.__code__
    name = hashlib.sha256(f"{code.co_filename}:{fn.__qualname__}:{code.co_firstlineno}".encode())
    try:
        stamp = cache_dir() / "numba-stamps" / name.hexdigest()[:32]
        if stamp.is_file() and read_bytes(stamp).decode() == digest:
            return
        dispatcher._cache.flush()  # numba's FunctionCache: drop every entry of the index
        stamp.parent.mkdir(mode=0o700, exist_ok=True)
        write_atomic(stamp, digest)
    except (OSError, AttributeError, UnicodeDecodeError):
        return  # no cache to keep (a read-only one): numba's own rules


def _hash_code(h, code) -> None:
    h.update(code.co_code)
    h.update(repr(code.co_names).encode())
    for const in code.co_consts:
        if hasattr(const, "co_code"):
            _hash_code(h, const)
        else:
            h.update(repr(const).encode())


def _function(obj):
    import types

    obj = getattr(obj, "py_func", obj)
    return obj if isinstance(obj, types.FunctionType) and not _library_module(obj) else None


def _library_module(obj) -> bool:
    name = getattr(obj, "__name__", "") if isinstance(obj, type(sys)) else obj.__module__ or ""
    return name.partition(".")[0] in ("numpy", "numba", "math", "cmath", "builtins")


def _code_names(code) -> set[str]:
    names = set(code.co_names)
    for const in code.co_consts:
        if hasattr(const, "co_names"):
            names |= _code_names(const)
    return names


def _assigned(cell) -> bool:
    try:
        cell.cell_contents  # noqa: B018 (an empty cell raises)
    except ValueError:
        return False
    return True


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


def compiled(kernel) -> bool:
    """True when numba dispatcher `kernel` is compiled: in this process, or in numba's
    on-disk cache (its index file exists; then using it costs a file read). The one place
    that reads numba's cache layout, which numba offers no public call for; another
    numba's layout counts as not compiled."""
    if kernel.signatures:
        return True
    try:
        return os.path.exists(kernel._cache._cache_file._index_path)
    except AttributeError:
        return False

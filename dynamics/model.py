"""`Model`: a declared system, its derived equations, and `compile()` to a `System`.

A registered model's cache key hashes the source of this package (models included), the
sympy version and the model's options, so a warm `compile()` loads the generated module
without importing sympy or building the model at all.
"""

from __future__ import annotations

import ast
import functools
import hashlib
import importlib
import importlib.util
import sysconfig
from collections.abc import Callable
from functools import cache
from importlib import metadata
from pathlib import Path

from . import cache as _cache
from . import checks
from .system import System

_REGISTRY: dict[str, str] = {
    "two_link_arm": "dynamics.models.arm:two_link_arm",
    "rolling_disk": "dynamics.models.disk:rolling_disk",
    "bead_on_rotating_rod": "dynamics.models.bead:bead_on_rotating_rod",
    "bead_on_driven_rod": "dynamics.models.bead:bead_on_driven_rod",
    "particle_cartesian": "dynamics.models.particles:particle_cartesian",
    "particle_cylindrical": "dynamics.models.particles:particle_cylindrical",
    "particle_spherical": "dynamics.models.particles:particle_spherical",
    "particle_nonholonomic": "dynamics.models.particles:particle_nonholonomic",
    "particle_parabolic_cylindrical": "dynamics.models.particles:particle_parabolic_cylindrical",
    "particle_on_curve": "dynamics.models.curve:particle_on_curve",
    "particle_on_4_sphere": "dynamics.models.sphere4:particle_on_4_sphere",
    "eccentric_disk_slider": "dynamics.models.crank:eccentric_disk_slider",
    "whipple_bicycle": "dynamics.models.bicycle:whipple_bicycle",
}


def register(name: str, target: str) -> None:
    """Register a model factory by import path 'package.module:function'."""
    _REGISTRY[name] = target


_CORE = (
    "spec.py",
    "calculus.py",
    "derive.py",
    "program.py",
    "codegen.py",
    "kernels.py",
    "lanes.py",
)


def _is_library(path: Path) -> bool:
    """Whether `path` belongs to the standard library or an installed package."""
    roots = {sysconfig.get_paths()[k] for k in ("stdlib", "platstdlib", "purelib", "platlib")}
    return any(path.is_relative_to(root) for root in roots)


def _factory_files(module: str) -> list[Path]:
    """The source file of the factory's module and of every module it imports that is not a
    library (one level: a constant imported from the user's other module changes the key)."""
    origin = Path(importlib.util.find_spec(module).origin)
    files = [origin]
    try:
        tree = ast.parse(origin.read_bytes())
    except (OSError, SyntaxError, ValueError):
        return files
    package = module.rpartition(".")[0]
    for node in ast.walk(tree):
        names = []
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parent = package.rsplit(".", node.level - 1)[0] if node.level > 1 else package
                base = f"{parent}.{base}".strip(".")
            names = [base] + [f"{base}.{a.name}".strip(".") for a in node.names]
        for name in names:
            try:
                spec = importlib.util.find_spec(name) if name else None
            except (ImportError, ValueError):
                spec = None
            path = Path(spec.origin) if spec is not None and spec.origin else None
            if path is not None and path.suffix == ".py" and not _is_library(path):
                files.append(path)
    return sorted(set(files))


@cache
def _code_fingerprint(target: str | None = None) -> str:
    """Hash of the sympy version, the files that derive and generate code, and, for a
    factory `target` ('module:function'), its module's source and the sources of the
    user's modules it imports (`_factory_files`)."""
    h = hashlib.sha256(metadata.version("sympy").encode())
    root = Path(__file__).parent
    paths = [root / name for name in _CORE]
    if target is not None:
        paths += _factory_files(target.split(":")[0])
    for path in paths:
        h.update(path.name.encode())
        h.update(path.read_bytes())
    return h.hexdigest()


def list_models() -> list[str]:
    """Names of the registered models."""
    return sorted(_REGISTRY)


def get_model(name: str, **options) -> Model:
    """The registered model `name`; `options` go to its factory (e.g. a curve)."""
    if not isinstance(name, str):
        raise TypeError(
            f"get_model: name must be a model name (str) such as 'two_link_arm', got {name!r}. "
            f"Known: {', '.join(list_models())}."
        )
    if name not in _REGISTRY:
        raise checks.unknown("model", name, list_models(), n=3)
    return Model(_REGISTRY[name], name=name, options=options)


def _import_factory(target: str) -> Callable:
    module, func = target.split(":")
    obj = importlib.import_module(module)
    for part in func.split("."):  # a qualified name: Class.method
        obj = getattr(obj, part)
    return obj


def factory_target(factory) -> str | None:
    """'module:qualname' of a factory that importing gives back (so that a warm cache is
    keyed by its source file and never rebuilds the spec), else None: a lambda, a local
    function, a functools.partial, a callable object, a function of __main__ (those are
    keyed by the spec they build)."""
    if isinstance(factory, staticmethod):
        factory = factory.__func__
    module = getattr(factory, "__module__", None)
    qualname = getattr(factory, "__qualname__", None)
    if not (isinstance(module, str) and isinstance(qualname, str)):
        return None
    if "<" in qualname or module == "__main__":
        return None
    target = f"{module}:{qualname}"
    try:
        found = _import_factory(target)
    except Exception:  # not importable as named
        return None
    found = found.__func__ if isinstance(found, staticmethod) else found
    return target if found is factory else None


def _label(factory) -> str:
    """A factory's name for messages: a function, a functools.partial, a callable object."""
    if isinstance(factory, functools.partial):
        return f"functools.partial({_label(factory.func)}, ...)"
    name = getattr(factory, "__qualname__", None) or type(factory).__qualname__ + " object"
    return repr(name)


class Model:
    """A mechanical system: its spec (what the book writes) and what is derived from it.

    Build one from a registered name (`get_model`) or from any `ModelSpec` or factory.
    """

    def __init__(self, spec_or_factory, name: str | None = None, options: dict | None = None):
        self._options = dict(options or {})
        if isinstance(spec_or_factory, str):  # a registered 'module:function', imported lazily
            self._factory = spec_or_factory
            self._spec = None
            self._registered = True
        elif callable(spec_or_factory) or isinstance(spec_or_factory, staticmethod):
            self._factory = spec_or_factory
            self._spec = None
            self._registered = False
        else:
            self._factory = None
            self._spec = spec_or_factory
            self._registered = False
        self.name = name or self.spec.name
        self._derived = None

    def __repr__(self) -> str:
        return f"Model({self.name!r})"

    @property
    def spec(self):
        if self._spec is None:
            factory = self._factory
            if isinstance(factory, str):
                factory = _import_factory(factory)
            if isinstance(factory, staticmethod):
                factory = factory.__func__
            from .spec import ModelSpec

            spec = factory(**self._options)
            if not isinstance(spec, ModelSpec):
                raise TypeError(
                    f"The model factory {_label(factory)} returned {type(spec).__name__}, not "
                    "a dynamics.ModelSpec (a factory is called with no arguments and returns "
                    "the spec)."
                )
            self._spec = spec
        return self._spec

    @property
    def derived(self):
        if self._derived is None:
            from .derive import derive

            self._derived = derive(self.spec)
        return self._derived

    @property
    def coordinates(self) -> tuple[str, ...]:
        return tuple(str(q.name) for q in self.spec.coordinates)

    @property
    def inputs(self) -> tuple[str, ...]:
        return tuple(str(u) for u in self.spec.inputs)

    @property
    def parameters(self) -> dict[str, float]:
        return {str(k): float(p.default) for k, p in self.spec.parameters.items()}

    @property
    def units(self) -> dict[str, str]:
        return {str(k): p.unit for k, p in self.spec.parameters.items()}

    def equations(self):
        """Lagrange's equations as a sympy Matrix, each entry = 0 (eq. 7.36 form)."""
        return self.derived.equations

    def mass_matrix(self):
        return self.derived.mass

    def forcing(self):
        return self.derived.forcing

    @property
    def key(self) -> str:
        """Cache key: everything the generated code depends on."""
        target = self._factory if isinstance(self._factory, str) else None
        h = hashlib.sha256(_code_fingerprint(target).encode())
        if self._registered:
            h.update(self.name.encode())
            if self._options:
                import sympy as sp

                h.update(sp.srepr(sorted(self._options.items())).encode())
        else:
            h.update(self.spec.fingerprint().encode())
        return h.hexdigest()

    def compile(self, **params) -> System:
        """A `System` with these parameter values (defaults otherwise), from the cache
        when possible; deriving and generating code only when it is not there."""
        key = self.key

        def build() -> str:
            from .codegen import generate

            return generate(self.derived, key)

        return System(_cache.load_or_build(self.name, key, build), params)

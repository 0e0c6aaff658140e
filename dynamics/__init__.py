"""Derive, compile and integrate Lagrangian models (no Gymnasium here).

>>> import dynamics
>>> arm = dynamics.get_model("two_link_arm")
>>> arm.equations()            # sympy Matrix, each entry = 0
>>> sys = arm.compile(m2=2.0)  # numeric System, cached on disk
>>> sys.state_derivative(0.0, [0.1, 0.2, 0.0, 0.0], [0.0, 0.0])
"""

from .angles import wrap
from .model import Model, get_model, list_models, register
from .system import System

__all__ = ["Model", "System", "get_model", "list_models", "register", "wrap"]

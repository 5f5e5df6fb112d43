"""Heavy libraries loaded when first used, so that importing the project, and starting the CLI, costs little
more than numpy: a command loads OpenCV, numba or scipy's signal tools only if it computes with them.

- :func:`library` stands for a library module at a module's top (``cv2 = library("cv2")``) and imports it
  at the first attribute read (``cv2.imdecode``).
- :func:`jit` is ``numba.njit(**options)`` applied when a compiled function is first called: numba and
  LLVM load then, and every kernel that :func:`jit` holds is compiled at once, so that one kernel calling
  another (by name, or as ``module.kernel``) finds numba's dispatcher, as with ``numba.njit`` at import.

Only third-party libraries are deferred: the project's own modules import each other at their top
(docs/extending.md), where the layer contracts see them.

Why not ``lazy_loader.load``: it finds the module's spec when called, which imports every parent package of a
submodule at once. ``lazy_loader.load("scipy.io.wavfile")`` imports ``scipy.io`` with its MATLAB, NetCDF and
Matrix Market readers, 270 ms of CPU at the import of the ingest readers that name it (measured against 0.0 ms
for :func:`library`, which imports nothing until an attribute is read), on every command that reads a
feature table.
"""

from __future__ import annotations

import functools
import importlib
import sys
import threading
import types
from collections.abc import Callable
from typing import Any, TypeVar

PROJECT_PACKAGES = ("scanner", "features", "taxonomy", "gui", "texplorer")
"""Top-level packages of the project, whose modules are never deferred."""

F = TypeVar("F", bound=Callable[..., Any])


class _Library(types.ModuleType):
    """A library module imported at its first attribute read; its names are then copied in, so that later
    reads cost what a module's do."""

    def __getattr__(self, name: str) -> Any:
        if name.startswith("__"):  # copy, pickle and doctest probe dunders; they do not need the library
            raise AttributeError(name)
        module = importlib.import_module(self.__name__)
        self.__dict__.update(vars(module))
        return getattr(module, name)


def library(name: str) -> types.ModuleType:
    """The module ``name`` if it is already imported, else a stand-in that imports it at its first use.

    Parameters
    ----------
    name : str
        Dotted name of a third-party module (``"cv2"``, ``"scipy.signal"``).

    Returns
    -------
    types.ModuleType
        The module, or a module object that imports it when an attribute is read.

    Raises
    ------
    ValueError
        If ``name`` is a module of the project: those are imported at a module's top.
    """
    if name.split(".")[0] in PROJECT_PACKAGES:
        raise ValueError(f"{name}: project modules are imported at the top of a module, not deferred")
    module = sys.modules.get(name)
    if module is None:
        module = _Library(name)
        _waiting.add(name)
    return module


_waiting: set[str] = set()
"""Libraries that a stand-in of :func:`library` was made for."""


def preload() -> None:
    """Import every library a stand-in was made for, and numba if a kernel waits for it: before forking
    worker processes, so that they share these modules instead of each importing its own (the kernels
    themselves are compiled, or loaded from numba's cache, in each worker at their first call)."""
    for name in sorted(_waiting):
        importlib.import_module(name)
    if _pending:
        importlib.import_module("numba")


class _Kernel:
    """A function :func:`jit` compiles at the first call of any deferred kernel."""

    def __init__(self, function: Callable[..., Any], options: dict[str, Any]) -> None:
        functools.update_wrapper(self, function)
        self.py_func = function
        self.options = options
        self.dispatcher: Any = None

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        if self.dispatcher is None:
            _compile_pending()
        return self.dispatcher(*args, **kwargs)

    def __getattr__(self, name: str) -> Any:  # numba's own attributes (signatures, inspect_types, ...)
        if name.startswith("__") or name == "dispatcher":
            raise AttributeError(name)
        if self.dispatcher is None:
            _compile_pending()
        return getattr(self.dispatcher, name)


_pending: list[_Kernel] = []
_lock = threading.Lock()


def jit(**options: Any) -> Callable[[F], F]:
    """``numba.njit(**options)``, applied at the first call of a deferred kernel instead of at import.

    Parameters
    ----------
    **options
        numba.njit's options (``cache``, ``nogil``, ``inline``, ...).

    Returns
    -------
    Callable
        A decorator; the function it returns calls the compiled kernel.
    """
    def decorate(function: F) -> F:
        kernel = _Kernel(function, options)
        with _lock:
            _pending.append(kernel)
        return kernel  # type: ignore[return-value]
    return decorate


def _compile_pending() -> None:
    """Make numba's dispatcher of every deferred kernel and put it in place of the stand-in, in the module
    that defines it and in every project module that imported it, before any of them compiles: numba reads
    a kernel's callees from its module's globals when it compiles it."""
    import numba

    with _lock:
        kernels = list(_pending)
        _pending.clear()
        for kernel in kernels:
            kernel.dispatcher = numba.njit(**kernel.options)(kernel.py_func)
        replaced = {id(kernel): kernel.dispatcher for kernel in kernels}
        defining = {kernel.py_func.__module__ for kernel in kernels}
        for name, module in list(sys.modules.items()):
            if module is None or (name.split(".")[0] not in PROJECT_PACKAGES and name not in defining):
                continue
            namespace = vars(module)
            for key, value in list(namespace.items()):
                if id(value) in replaced and isinstance(value, _Kernel):
                    namespace[key] = replaced[id(value)]


def optional(name: str, extra: str, purpose: str) -> types.ModuleType:
    """Import the optional library ``name``, or say in one line which extra installs it.

    Parameters
    ----------
    name : str
        The library's module (``"pandas"``).
    extra : str
        The ``texplorer`` extra that installs it (``pip install 'texplorer[pandas]'``).
    purpose : str
        What needs it, for the message (``"FeatureSpace.to_pandas()"``).

    Returns
    -------
    types.ModuleType
        The imported module.

    Raises
    ------
    ModuleNotFoundError
        The library is not installed.
    """
    try:
        return importlib.import_module(name)
    except ModuleNotFoundError as missing:
        if missing.name != name.split(".")[0] and missing.name != name:
            raise  # the library is there but something it needs is not: its own message says what
        raise ModuleNotFoundError(f"{purpose} needs {name}, which is not installed: "
                                  f"pip install 'texplorer[{extra}]'", name=name) from None

"""Heavy libraries loaded when first used, so that importing the project, and starting the CLI, costs little
more than numpy: a command loads OpenCV, numba or scipy's signal tools only if it computes with them.

- :func:`library` stands for a library module at a module's top (``cv2 = library("cv2")``) and imports it
  at the first attribute read (``cv2.imdecode``).
- :func:`jit` is ``numba.njit(**options)`` applied when a compiled function is first called: numba and
  LLVM load then, and that kernel compiles (or loads from numba's cache) with the kernels it calls. numba
  types a stand-in it meets in a kernel's globals as the stand-in's own dispatcher, so a kernel calling
  another (by name, or as ``module.kernel``) compiles as with ``numba.njit`` at import, and no module's
  globals are rewritten.

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


def library(name: str, *, workers: bool = True) -> types.ModuleType:
    """The module ``name`` if it is already imported, else a stand-in that imports it at its first use.

    Parameters
    ----------
    name : str
        Dotted name of a third-party module (``"cv2"``, ``"scipy.signal"``).
    workers : bool, default True
        Whether worker processes use it: the libraries they use are imported before they are forked
        (:func:`preload`); one only this process uses (matplotlib, which draws the reports) is not.

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
        if workers:
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
    if _kernels:
        _numba()


class _Kernel:
    """A function :func:`jit` hands to numba when it is first called, or first compiled into another kernel.

    numba types a kernel it finds in a module's globals through :func:`_typeof_kernel` as its own dispatcher,
    so a kernel calling another by name (or as ``module.kernel``, inlined or not) compiles as with
    ``numba.njit`` at import, and the module's globals keep the stand-in."""

    def __init__(self, function: Callable[..., Any], options: dict[str, Any]) -> None:
        functools.update_wrapper(self, function)
        self.py_func = function
        self.options = options
        self._dispatcher: Any = None

    @property
    def dispatcher(self) -> Any:
        """numba's dispatcher of this kernel (``numba.njit(**options)(py_func)``), made at its first use;
        numba compiles it, or loads it from its cache (``cache=True``), at its first call."""
        if self._dispatcher is None:
            with _lock:
                if self._dispatcher is None:
                    numba = _numba()
                    self._dispatcher = numba.njit(**self.options)(self.py_func)
        return self._dispatcher

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        return self.dispatcher(*args, **kwargs)

    def __getattr__(self, name: str) -> Any:  # numba's own attributes (signatures, inspect_types, ...)
        if name.startswith("__") or name in ("dispatcher", "_dispatcher"):
            raise AttributeError(name)
        return getattr(self.dispatcher, name)


_kernels: list[_Kernel] = []
"""Every kernel :func:`jit` made (for :func:`preload`)."""
_lock = threading.RLock()


def jit(**options: Any) -> Callable[[F], F]:
    """``numba.njit(**options)``, applied at the first call of a kernel instead of at import.

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
            _kernels.append(kernel)
        return kernel  # type: ignore[return-value]
    return decorate


@functools.cache
def _numba() -> types.ModuleType:
    """numba, imported at the first kernel's first use, told once to type a stand-in as its dispatcher."""
    import numba
    from numba.extending import typeof_impl

    typeof_impl.register(_Kernel)(_typeof_kernel)
    return numba


def _typeof_kernel(kernel: _Kernel, context: Any) -> Any:
    """numba's type of a kernel's stand-in met in compiled code: the type of its own dispatcher."""
    from numba.core import types as numba_types

    return numba_types.Dispatcher(kernel.dispatcher)


def optional(name: str, extra: str | None, purpose: str, *, install: str | None = None,
             error: type[Exception] = ModuleNotFoundError) -> types.ModuleType:
    """Import the optional library ``name``, or say in one line what needs it and how to install it.

    Parameters
    ----------
    name : str
        The library's module (``"pandas"``, ``"nidaqmx.stream_readers"``).
    extra : str or None
        The ``texplorer`` extra that installs it (``pip install 'texplorer[pandas]'``), if one does.
    purpose : str
        What needs it, for the message (``"FeatureSpace.to_pandas()"``).
    install : str, optional
        The command that installs it, where no extra does (``"pip install pyserial"``).
    error : type of Exception
        What is raised when it is missing (a device's ``DeviceUnavailable``, the cluster's ``ClusterError``).

    Returns
    -------
    types.ModuleType
        The imported module.

    Raises
    ------
    ModuleNotFoundError
        Or ``error``: the library is not installed. With an ``error`` of its own, a library that is there but
        cannot be imported (something it needs is missing or broken) raises ``error`` too, naming why.

    Examples
    --------
    >>> from scanner.lazy import optional
    >>> optional("json", None, "reading settings").__name__
    'json'
    >>> optional("no_such_library", "cluster", "running on a Dask cluster")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    ModuleNotFoundError: running on a Dask cluster needs no_such_library, which is not installed: pip install ...
    """
    try:
        return importlib.import_module(name)
    except ImportError as failed:
        absent = isinstance(failed, ModuleNotFoundError) and failed.name in (name, name.split(".")[0])
        if not absent and error is ModuleNotFoundError:
            raise  # the library is there but something it needs is not, or is broken: its own message says what
        how = install or f"pip install 'texplorer[{extra}]'"
        why = "which is not installed" if absent else f"which cannot be imported ({failed})"
        message = f"{purpose} needs {name}, {why}: {how}"
        if error is ModuleNotFoundError:
            raise ModuleNotFoundError(message, name=name) from None
        raise error(message) from None

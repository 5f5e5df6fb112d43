"""scanner.lazy: libraries imported at their first use, numba kernels compiled at their first call."""

from __future__ import annotations

import subprocess
import sys
import textwrap

import numpy as np
import pytest

from scanner import lazy


def test_a_library_stand_in_imports_the_library_at_its_first_attribute_read():
    code = textwrap.dedent("""
        import sys
        from scanner.lazy import library
        wave = library("wave")
        print("wave" in sys.modules)
        print(wave.WAVE_FORMAT_PCM == __import__("wave").WAVE_FORMAT_PCM, "wave" in sys.modules)
    """)
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, run.stderr
    assert run.stdout.split() == ["False", "True", "True"]


def test_an_imported_library_is_given_as_it_is():
    assert lazy.library("numpy") is np


@pytest.mark.parametrize("name", ["scanner.scan", "features", "texplorer"])
def test_project_modules_are_not_deferred(name):
    with pytest.raises(ValueError, match="imported at the top"):
        lazy.library(name)


def test_kernels_calling_kernels_compile_at_the_first_call_without_rewriting_globals():
    # A fresh interpreter: the kernels of this module must be pending when the first one is called.
    code = textwrap.dedent("""
        import sys
        import numpy as np
        from scanner.lazy import jit

        @jit(cache=False, inline="always")
        def square(x):
            return x * x

        @jit(cache=False, nogil=True)
        def sum_of_squares(values):
            total = 0.0
            for v in values:
                total += square(v)
            return total

        print("numba" in sys.modules)
        print(sum_of_squares(np.arange(4.0)), type(sum_of_squares).__module__.split(".")[0])
        print(type(globals()["square"]).__module__.split(".")[0], square(3.0))
    """)
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
    # 0 + 1 + 4 + 9 = 14; the first call compiled the callee too (inlined), and the module's globals keep the
    # stand-ins: numba types them as their dispatchers, nothing rewrites another module's names
    assert run.stdout.split() == ["False", "14.0", "scanner", "scanner", "9.0"]


def test_preload_imports_the_libraries_waiting_behind_stand_ins():
    code = textwrap.dedent("""
        import sys
        import features  # stand-ins for cv2, pywt, scipy.signal, ...; kernels waiting for numba
        from scanner.lazy import preload
        print(sorted(m for m in ("cv2", "numba", "pywt", "scipy.signal") if m in sys.modules))
        preload()
        print(sorted(m for m in ("cv2", "numba", "pywt", "scipy.signal") if m in sys.modules))
    """)
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
    assert run.stdout.splitlines() == ["[]", "['cv2', 'numba', 'pywt', 'scipy.signal']"]


def test_compile_kernels_leaves_nothing_for_a_database_of_scans_to_compile():
    # A fresh interpreter, so that what is compiled is what compile_kernels asked for: afterwards the scans
    # of other materials, photo sizes and fold outcomes, in memory and read back, add no signature to any
    # kernel (each added one would be a compilation in every worker of the first texplorer demo).
    code = textwrap.dedent("""
        import tempfile, warnings, pathlib
        from features import extract
        from scanner import lazy
        from scanner.simulation import synthetic_scan
        from scanner.storage.matfile import load_scan, save_scan
        from scanner.workflows.demo import compile_kernels

        def signatures():  # every kernel of the project, with the signatures numba compiled of it
            return {f"{k.py_func.__module__}.{k.__qualname__}": len(k._dispatcher.signatures) if k._dispatcher else 0
                    for k in lazy._kernels}

        compile_kernels()
        before = signatures()
        warnings.simplefilter("ignore")
        folder = pathlib.Path(tempfile.mkdtemp())
        for seed, (material, size, skip) in enumerate([("oak-planed", 512, 0.0), ("float-glass", 384, 0.0),
                                                       ("polyurethane-foam", 384, 0.5), ("C2S3M1P1X1", 400, 1.0)]):
            scan = synthetic_scan(material, seed=seed + 7, image_size=(size, size), fold_skip_probability=skip)
            save_scan(scan, folder / f"{seed}.mat")
            extract(scan)
            extract(load_scan(folder / f"{seed}.mat"))
        after = signatures()
        added = {k: (before.get(k), n) for k, n in after.items() if n != before.get(k)}
        print(sum(n > 0 for n in before.values()), added)
    """)
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stderr
    compiled, added = run.stdout.split(maxsplit=1)
    assert int(compiled) >= 15  # the feature and preprocessing kernels (inlined helpers compile inside their callers)
    assert added.strip() == "{}"


def test_a_library_workers_do_not_use_is_not_preloaded():
    code = textwrap.dedent("""
        import sys
        from scanner import lazy
        lazy.library("colorsys", workers=False)
        lazy.library("wave")
        lazy.preload()
        print("colorsys" in sys.modules, "wave" in sys.modules)
    """)
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, run.stderr
    assert run.stdout.split() == ["False", "True"]


class _Unavailable(RuntimeError):
    """A caller's own error (a device's DeviceUnavailable, the cluster's ClusterError)."""


def test_an_optional_library_missing_or_broken_says_what_needs_it_in_the_caller_s_error(tmp_path, monkeypatch):
    (tmp_path / "broken_driver.py").write_text("raise ImportError('libdriver.so.1: cannot open shared object file')\n")
    (tmp_path / "needy_driver.py").write_text("import no_such_dependency_of_it\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    with pytest.raises(_Unavailable, match=r"^the board needs no_such_driver, which is not installed: "
                                           r"pip install no-such-driver$"):
        lazy.optional("no_such_driver", None, "the board", install="pip install no-such-driver", error=_Unavailable)
    with pytest.raises(_Unavailable, match=r"^the board needs broken_driver, which cannot be imported "
                                           r"\(libdriver.so.1: cannot open shared object file\): pip install x$"):
        lazy.optional("broken_driver", None, "the board", install="pip install x", error=_Unavailable)
    with pytest.raises(_Unavailable, match=r"needs needy_driver, which cannot be imported \(No module named "
                                           r"'no_such_dependency_of_it'\)"):
        lazy.optional("needy_driver", None, "the board", install="pip install x", error=_Unavailable)
    # Without an error of the caller's: a missing library as ModuleNotFoundError naming the extra; a library
    # that is there but broken keeps its own error.
    with pytest.raises(ModuleNotFoundError, match=r"pip install 'texplorer\[cluster\]'$"):
        lazy.optional("no_such_driver", "cluster", "the cluster")
    with pytest.raises(ModuleNotFoundError, match="no_such_dependency_of_it"):
        lazy.optional("needy_driver", "cluster", "the cluster")
    with pytest.raises(ImportError, match="libdriver.so.1"):
        lazy.optional("broken_driver", "cluster", "the cluster")

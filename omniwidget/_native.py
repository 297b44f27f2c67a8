"""The compiled kernels in a fresh process without numba: their machine code kept on disk, loaded by llvmlite.

Issue 18, part 1. Reading a kernel from numba's own cache still costs a new process about
half a second before the kernel runs: importing numba, then building its typing and target
contexts at the first call (hundreds of modules: numba's whole library of numpy and
Python implementations, cffi, a BLAS check that imports scipy.linalg). That is more than
the kernels' whole work on a 2048-wide panorama, and more than the rest of a warp's start.

So once numba has compiled a kernel of :mod:`omniwidget._numba_kernels` for the
argument types a warp gives it, that kernel is compiled once more as a plain C function (a
numba ``cfunc`` that makes arrays of its pointer arguments and calls the kernel, which
numba links in whole) and its machine code is written next to numba's cache: per
installation and argument types, like numba's cache, never per input. Later processes load
it with llvmlite alone (its import and a JIT engine: tens of milliseconds), call it through
ctypes, which releases the GIL as the kernels' ``nogil`` does, and never import numba.
The instructions are those numba generates for the kernel on C-contiguous arrays, so the
results are bit for bit those of numba's own dispatch.

A stored kernel is used only when its file says it was built from the same
``_numba_kernels.py`` (its bytes), numba, llvmlite, Python, file format and CPU (name and
features); otherwise numba runs it and the file is rebuilt in place (one file per kernel,
argument types and CPU: the folder does not grow). Numba runs a kernel itself, as before,
when no stored copy fits, when an array is not C-contiguous, aligned and writeable, once
:mod:`omniwidget._numba_kernels` is imported in the process (numba is paid for
then, and its cache statistics stay whole), or with ``OMNIWIDGET_NATIVE=0``.

The files live where numba keeps its cache for ``_numba_kernels.py``: in
``NUMBA_CACHE_DIR`` when set, else in the package's ``__pycache__`` folder when it can be
written, else in the user's cache folder.
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
import struct
import sys
import threading
from collections.abc import Callable
from functools import cache
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["ENV", "FORMAT", "Kernels", "enabled", "kernels", "stored_files"]

_log = logging.getLogger("omniwidget")

#: Set to ``0`` to run the kernels through numba only (no stored native code read or written).
ENV = "OMNIWIDGET_NATIVE"
#: Version of the stored files and of the wrappers compiled into them; a change rebuilds them.
FORMAT = 1
_MODULE = "omniwidget._numba_kernels"
_SOURCE = Path(__file__).with_name("_numba_kernels.py")
_MAGIC = b"OWNATIVE"
_SCALARS = {"<f8": "c_double", "<f4": "c_float", "<i8": "c_int64", "<i4": "c_int32", "|b1": "c_bool"}
_ARRAYS = frozenset({"<f8", "<f4", "<i8", "<i4", "|b1"})

_lock = threading.RLock()
_state: dict[str, Any] = {}
_MISSING = object()


@cache
def available() -> bool:
    """Whether the compiled kernels can be used: numba is installed and ``OMNIWIDGET_NUMBA`` is not ``0``.

    Numba is looked for, not imported: a process that finds every kernel it needs stored
    natively never imports it. The one place that chooses between the compiled kernels and
    the numpy path (:mod:`omniwidget.raster._kernels` re-exports it).
    """
    if os.environ.get("OMNIWIDGET_NUMBA", "1") == "0":
        return False
    import importlib.util

    try:
        return importlib.util.find_spec("numba") is not None
    except (ImportError, ValueError):
        return False


def enabled() -> bool:
    """Whether stored native kernels may be read and written: ``OMNIWIDGET_NATIVE`` is not ``0`` and numba's JIT is not disabled."""
    return os.environ.get(ENV, "1") != "0" and os.environ.get("NUMBA_DISABLE_JIT", "0") in ("", "0")


# --- argument types --------------------------------------------------------------------------
def _signature(args: tuple) -> tuple[tuple | None, bool]:
    """The arguments' types as the stored kernels know them, and whether a stored kernel may take them.

    Arrays are ``(dtype, ndim)``; Python ints, floats and bools are numba's int64, float64
    and boolean; None for an argument of any other kind (numba only). A stored kernel takes
    C-contiguous, aligned, writeable arrays, as pointers: the type numba gives such an array
    is the one the stored copy's wrapper hands the kernel, so building it compiles no second
    specialisation, and a kernel runs natively only on what numba would have run it on.
    """
    key: list[tuple[str, int] | str] = []
    plain = True
    for a in args:
        if isinstance(a, np.ndarray):
            code = a.dtype.str
            if code not in _ARRAYS or a.ndim == 0:
                return None, False
            flags = a.flags
            plain = plain and flags.c_contiguous and flags.aligned and flags.writeable
            key.append((code, a.ndim))
            continue
        if isinstance(a, (bool, np.bool_)):
            code = "|b1"
        elif isinstance(a, int):
            code = "<i8" if -(2**63) <= a < 2**63 else ""
        elif isinstance(a, float):
            code = "<f8"
        elif isinstance(a, (np.integer, np.floating)):
            code = a.dtype.str
        else:
            code = ""
        if code not in _SCALARS:
            return None, False
        key.append(code)
    return tuple(key), plain


def _flat(args: tuple) -> list:
    """The C arguments: each array as its data pointer followed by its shape."""
    out: list = []
    for a in args:
        if isinstance(a, np.ndarray):
            out.append(a.ctypes.data)
            out.extend(a.shape)
        elif isinstance(a, (bool, np.bool_)):
            out.append(bool(a))
        elif isinstance(a, (int, np.integer)):
            out.append(int(a))
        else:
            out.append(float(a))
    return out


# --- where and what ---------------------------------------------------------------------------
def _digest(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def _stamp() -> dict[str, Any]:
    """What a stored kernel must have been built with to be used here (computed once per process)."""
    stamp = _state.get("stamp")
    if stamp is None:
        import importlib.util

        import llvmlite

        spec = importlib.util.find_spec("numba")  # finds numba without importing it
        if spec is None or spec.origin is None:
            raise ImportError("numba is not installed")
        version = Path(spec.origin).with_name("_version.py")
        ll = _llvm()
        features = ll.get_host_cpu_features().flatten()
        stamp = {
            "format": FORMAT,
            "source": _digest(_SOURCE.read_bytes()),
            "numba": _digest(version.read_bytes() if version.exists() else spec.origin.encode()),
            "llvmlite": llvmlite.__version__,
            "python": sys.implementation.cache_tag,
            "cpu": [ll.get_process_triple(), ll.get_host_cpu_name(), features],
        }
        _state["stamp"] = stamp
    return stamp


def _folders() -> list[Path]:
    """Where the stored kernels may be, first choice first (numba's choice of cache folder)."""
    env = os.environ.get("NUMBA_CACHE_DIR")
    if env:
        return [Path(env) / "omniwidget-native"]
    user = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "omniwidget" / "native"
    return [_SOURCE.parent / "__pycache__", user]


def _file_name(name: str, key: tuple) -> str:
    """One file per kernel, argument types, Python and CPU: rebuilt in place when anything else changes."""
    stamp = _stamp()
    which = _digest(repr((key, stamp["python"], stamp["cpu"])).encode())[:16]
    return f"_numba_kernels.{name}.{which}.native"


def _read(name: str, key: tuple) -> tuple[dict, bytes] | None:
    """The stored kernel's header and machine code, when a file fits this process; else None."""
    want = {**_stamp(), "kernel": name, "key": repr(key)}
    file_name = _file_name(name, key)
    for folder in _folders():
        try:
            data = (folder / file_name).read_bytes()
        except OSError:
            continue
        if not data.startswith(_MAGIC) or len(data) < len(_MAGIC) + 4:
            continue
        (size,) = struct.unpack_from("<I", data, len(_MAGIC))
        start = len(_MAGIC) + 4
        try:
            header = json.loads(data[start : start + size])
        except ValueError:
            continue
        if all(header.get(k) == v for k, v in want.items()):
            return header, data[start + size :]
    return None


def _write(name: str, key: tuple, header: dict, code: bytes) -> Path | None:
    """Store a kernel whole (temporary file and rename) in the first folder that can be written."""
    payload = json.dumps(header, sort_keys=True).encode()
    data = _MAGIC + struct.pack("<I", len(payload)) + payload + code
    for folder in _folders():
        try:
            folder.mkdir(parents=True, exist_ok=True)
            path = folder / _file_name(name, key)
            tmp = folder / f".{path.name}.{os.getpid()}.{threading.get_ident()}.tmp"
            tmp.write_bytes(data)
            os.replace(tmp, path)
            return path
        except OSError:
            continue
    return None


def stored_files() -> list[Path]:
    """The stored kernels of this installation (for inspection and tests)."""
    return sorted(p for folder in _folders() if folder.is_dir() for p in folder.glob("_numba_kernels.*.native"))


# --- loading without numba -----------------------------------------------------------------
def _llvm() -> Any:
    """The binding layer of llvmlite, with the native target ready (what numba initialises)."""
    ll = _state.get("llvm")
    if ll is None:
        import llvmlite.binding as binding

        binding.initialize_native_target()
        binding.initialize_native_asmprinter()
        ll = _state["llvm"] = binding
    return ll


def _undefined_elf(code: bytes) -> list[str] | None:
    """The undefined symbols of a little-endian ELF64 object, or None for another format."""
    if code[:4] != b"\x7fELF" or code[4] != 2 or code[5] != 1:
        return None
    (shoff,) = struct.unpack_from("<Q", code, 0x28)
    shentsize, shnum = struct.unpack_from("<HH", code, 0x3A)
    sections = [struct.unpack_from("<IIQQQQIIQQ", code, shoff + i * shentsize) for i in range(shnum)]
    names = []
    for _, kind, _, _, offset, size, link, _, _, entsize in sections:
        if kind != 2:  # SHT_SYMTAB
            continue
        strtab = sections[link]
        strings = code[strtab[4] : strtab[4] + strtab[5]]
        for at in range(offset, offset + size, entsize or 24):
            st_name, _, _, st_shndx = struct.unpack_from("<IBBH", code, at)
            if st_shndx == 0 and st_name:
                names.append(strings[st_name : strings.index(b"\0", st_name)].decode())
    return names


def _symbol_address(name: str) -> int | None:
    """Where an external symbol of a stored kernel is in this process, as numba would bind it.

    Python's C API from the process, its exception types and None as numba binds them (the
    objects themselves), the C library's functions; numba's own helpers (numba_*, NRT_*),
    reached only on the error paths of a kernel that cannot fail (nothing raises, nothing
    is allocated), to ``abort``: nothing can go on silently from there.
    """
    import builtins
    import ctypes

    process = _state.get("process")
    if process is None:
        process = _state["process"] = ctypes.CDLL(None)
    if name.startswith("PyExc_") and isinstance(getattr(builtins, name[6:], None), type):
        return id(getattr(builtins, name[6:]))
    if name == "_Py_NoneStruct":
        return id(None)
    try:
        return ctypes.cast(getattr(process, name), ctypes.c_void_p).value
    except AttributeError:
        if name.startswith(("numba_", "NRT_")):
            return ctypes.cast(process.abort, ctypes.c_void_p).value
    return None


def _load(header: dict, code: bytes) -> Callable[..., None]:
    """Link a stored kernel into a JIT engine of its own; returns the ctypes function (which releases the GIL)."""
    import ctypes

    ll = _llvm()
    for name in header["undefined"]:
        if not ll.address_of_symbol(name):
            address = _symbol_address(name)
            if address is None:
                raise LookupError(f"the stored kernel needs {name}, which this process does not have")
            ll.add_symbol(name, address)
    machine = _state.get("machine")
    if machine is None:
        machine = _state["machine"] = ll.Target.from_default_triple().create_target_machine()
    engine = ll.create_mcjit_compiler(ll.parse_assembly(""), machine)
    engine.add_object_file(ll.ObjectFileRef.from_data(code))
    engine.finalize_object()
    address = engine.get_function_address(header["symbol"])
    if not address:
        raise LookupError(f"{header['symbol']} is not in the stored kernel")
    _state.setdefault("engines", []).append(engine)  # the code lives as long as its engine
    argtypes = []
    for arg in header["args"]:
        if isinstance(arg, list):  # an array: its data pointer, then its shape
            argtypes += [ctypes.c_void_p] + [ctypes.c_int64] * arg[1]
        else:
            argtypes.append(getattr(ctypes, _SCALARS[arg]))
    return ctypes.CFUNCTYPE(None, *argtypes)(address)


# --- building with numba ------------------------------------------------------------------------
def _build(name: str, dispatcher: Any, key: tuple) -> tuple[dict, bytes, Any]:
    """Compile ``dispatcher`` as a C function of pointers and shapes; its header, machine code and the numba cfunc."""
    from numba import carray, cfunc, types
    from numba.np.numpy_support import from_dtype

    params, call, argtypes = [], [], []
    for i, code in enumerate(key):
        if isinstance(code, tuple):
            dims = [f"n{i}_{k}" for k in range(code[1])]
            params += [f"p{i}", *dims]
            call.append(f"carray(p{i}, ({', '.join(dims)},))")
            argtypes += [types.CPointer(from_dtype(np.dtype(code[0])))] + [types.int64] * code[1]
        else:
            params.append(f"a{i}")
            call.append(f"a{i}")
            argtypes.append(from_dtype(np.dtype(code)))
    namespace = {"kernel": dispatcher, "carray": carray}
    exec(f"def {name}_native({', '.join(params)}):\n    kernel({', '.join(call)})\n", namespace)  # noqa: S102
    # a C callback is always compiled in nopython mode; Any: numba's private _library below is in no stub
    compiled: Any = cfunc(types.void(*argtypes))(namespace[f"{name}_native"])
    ll = _llvm()
    library = compiled._library
    module = ll.parse_bitcode(library._final_module.as_bitcode())
    code = library._codegen._tm.emit_object(module)
    undefined = _undefined_elf(code)
    if undefined is None:
        undefined = [f.name for f in module.functions if f.is_declaration and not f.name.startswith("llvm.")]
        undefined += [g.name for g in module.global_variables if g.is_declaration]
    header = {
        **_stamp(),
        "kernel": name,
        "key": repr(key),
        "args": [list(c) if isinstance(c, tuple) else c for c in key],
        "symbol": compiled.native_name,
        "undefined": sorted(set(undefined)),
    }
    return header, code, compiled


# --- the kernels -------------------------------------------------------------------------------
def _as_imported(dispatcher: Any) -> bool:
    """Whether ``_numba_kernels.py`` is as it was when the process imported it (numba's own stamp of the source)."""
    try:
        cache = dispatcher._cache
        then, now = cache._cache_file._source_stamp, cache._impl.locator.get_source_stamp()
    except (AttributeError, OSError):  # another numba: the source's digest, taken before the import, is the check
        return True
    return bool(then == now)


class _quiet:
    """Swallow (and log) any failure: stored kernels are an optimisation, numba runs the kernels without them."""

    def __enter__(self) -> None:
        return None

    def __exit__(self, kind: Any, exc: BaseException | None, tb: Any) -> bool:
        if exc is not None and isinstance(exc, Exception):
            _log.debug("stored kernels: %s", exc)
            return True
        return False


class _Kernel:
    """One kernel of :mod:`omniwidget._numba_kernels`: its stored native code when it fits, else numba's dispatch."""

    def __init__(self, name: str) -> None:
        self.__name__ = name
        self._native: dict[tuple, Any] = {}  # key -> ctypes function, or None: not stored (numba runs it)
        self._checked: set[tuple] = set()  # keys whose stored file was made sure of in this process

    def __call__(self, *args: Any) -> None:
        key, plain = _signature(args)
        if key is not None and plain and enabled() and _MODULE not in sys.modules:
            fn = self._native.get(key, _MISSING)
            if fn is _MISSING:
                fn = self._open(key)
            if fn is not None:
                fn(*_flat(args))
                return
        if plain and enabled() and key not in self._checked and _MODULE not in sys.modules:
            with _lock, _quiet():
                _stamp()  # the kernels' source as numba is about to read it (a later edit is not built)
        from . import _numba_kernels

        dispatcher = getattr(_numba_kernels, self.__name__)
        dispatcher(*args)
        if key is not None and plain and enabled() and key not in self._checked:
            self._store(dispatcher, key)

    def _open(self, key: tuple) -> Any:
        with _lock:
            fn = self._native.get(key, _MISSING)
            if fn is _MISSING:
                fn = None
                try:
                    stored = _read(self.__name__, key)
                    if stored is not None:
                        fn = _load(*stored)
                except Exception as exc:  # noqa: BLE001 - numba runs the kernel instead
                    _log.debug("stored kernel %s not loaded: %s", self.__name__, exc)
                self._native[key] = fn
            return fn

    def _store(self, dispatcher: Any, key: tuple) -> None:
        """Make sure the stored copy for ``key`` exists and fits (numba has just compiled or read the kernel for it)."""
        with _lock:
            if key in self._checked:
                return
            self._checked.add(key)
            try:
                if _read(self.__name__, key) is None:
                    if _digest(_SOURCE.read_bytes()) != _stamp()["source"] or not _as_imported(dispatcher):
                        return  # the kernels' source changed since this process read it: the next process builds
                    header, code, compiled = _build(self.__name__, dispatcher, key)
                    _write(self.__name__, key, header, code)
                    _state.setdefault("cfuncs", []).append(compiled)
            except Exception as exc:  # noqa: BLE001 - the next process runs numba as this one did
                _log.debug("stored kernel %s not built: %s", self.__name__, exc)


class Kernels:
    """The kernels by name, as :mod:`omniwidget._numba_kernels` has them (``kernels().fold_rows(...)``)."""

    def __init__(self) -> None:
        self._kernels: dict[str, _Kernel] = {}

    def __getattr__(self, name: str) -> _Kernel:
        if name.startswith("_") or not name.isidentifier():
            raise AttributeError(name)
        kernel = self._kernels.get(name)
        if kernel is None:
            kernel = self._kernels.setdefault(name, _Kernel(name))
        return kernel


_KERNELS = Kernels()


def kernels() -> Kernels:
    """The kernels (one object per process)."""
    return _KERNELS

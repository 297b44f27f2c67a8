"""The compiled kernels in a fresh process without numba: their machine code kept on disk, loaded by llvmlite.

Reading a kernel from numba's own cache still costs a new process a long wait before the
kernel runs: importing numba, then building its typing and target contexts at the first call (hundreds of modules: numba's whole library of numpy and
Python implementations, cffi, a BLAS check that imports scipy.linalg). That is more than
the kernels' whole work on a 2048-wide panorama, and more than the rest of a warp's start.

So once numba has compiled a kernel of :mod:`omniwidget._numba_kernels` for the
argument types a warp gives it, that kernel is compiled once more as a plain C function (a
numba ``cfunc`` that makes arrays of its pointer arguments and calls the kernel, which
numba links in whole) and its machine code is written next to numba's cache: per
installation and argument types, like numba's cache, never per input. Later processes load
it with llvmlite alone (its import and a JIT engine), call it through
ctypes, which releases the GIL as the kernels' ``nogil`` does, and never import numba.
The instructions are those numba generates for the kernel on C-contiguous arrays, so the
results are bit for bit those of numba's own dispatch.

A stored kernel is used only when its file says it was built from the same
``_numba_kernels.py`` (its bytes), numba, llvmlite, Python, file format and CPU (name and
features); otherwise numba runs it and the file is rebuilt in place (one file per kernel,
argument types and CPU: the folder does not grow). Numba runs a kernel itself when no
stored copy fits, when an array is not C-contiguous, aligned and writeable, once
:mod:`omniwidget._numba_kernels` is imported in the process (numba is paid for
then, and its cache statistics stay whole), or with ``OMNIWIDGET_NATIVE=0``.

The files live where numba keeps its cache for ``_numba_kernels.py``: in
``NUMBA_CACHE_DIR`` when set, else in the package's ``__pycache__`` folder when it can be
written; else, or when that folder is not ours (below), in the user's cache folder.

Machine code is run only when it is ours, as ssh trusts its files: the
file is a regular file (not a symbolic link) owned by the user or root and not writable by
group or others, and so is its folder and every folder above it up to ``/`` (a folder above
may be writable by others when it is sticky, as ``/tmp`` is; a group of the user alone, a
user private group, counts as the user, as Debian's ssh has it). Each file ends with an
HMAC-SHA256 of everything before it, keyed by a secret of the user's (32 random bytes in
``omniwidget/native.key`` of the user's cache folder, mode 0600, made on first use), checked
before a byte of it is loaded. A file that fails is not loaded: numba runs the kernel and
the file is stored again, and why is logged once per process (a warning when a file was
altered or is not ours, at debug level for a folder that is not ours, which stays so).
Numba's own cache of the kernels is held to the same rule (:func:`secure_numba_cache`):
numba unpickles its index files, which can run any code.
"""

from __future__ import annotations

import builtins
import ctypes
import errno
import hashlib
import hmac
import importlib
import importlib.util
import json
import logging
import os
import secrets
import stat
import struct
import sys
import threading
from collections.abc import Callable
from functools import cache
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ._lazy import lazy, resolve

if TYPE_CHECKING:
    import grp
    import pwd

    import llvmlite
    import llvmlite.binding as binding
    import numba
    from numba.core import caching
    from numba.np import numpy_support

    from . import _numba_kernels
else:
    grp = lazy("grp")  # POSIX only, asked only where files have owners
    pwd = lazy("pwd")
    llvmlite = lazy("llvmlite")
    binding = lazy("llvmlite.binding")
    numba = lazy("numba")  # only to build a stored kernel or run one: a process that finds them stored never imports it
    caching = lazy("numba.core.caching")
    numpy_support = lazy("numba.np.numpy_support")
    _numba_kernels = lazy("omniwidget._numba_kernels")

__all__ = ["ENV", "FORMAT", "Kernels", "enabled", "kernels", "secure_numba_cache", "stored_files"]

_log = logging.getLogger("omniwidget")

#: Set to ``0`` to run the kernels through numba only (no stored native code read or written).
ENV = "OMNIWIDGET_NATIVE"
#: Version of the stored files and of the wrappers compiled into them; a change rebuilds them.
FORMAT = 2
_MODULE = "omniwidget._numba_kernels"
_SOURCE = Path(__file__).with_name("_numba_kernels.py")
_MAGIC = b"OWNATIVE"
_TAG = 32  # the HMAC-SHA256 that ends a stored file
_LARGEST = 1 << 26  # bytes: a stored kernel is tens of kilobytes; a larger file is not read
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


def _user_cache() -> Path:
    """The user's own cache folder of omniwidget (``$XDG_CACHE_HOME/omniwidget``, else ``~/.cache/omniwidget``)."""
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "omniwidget"


def _folders() -> list[Path]:
    """Where the stored kernels may be, first choice first: numba's choice of cache folder, then the user's cache."""
    env = os.environ.get("NUMBA_CACHE_DIR")
    first = Path(env) / "omniwidget-native" if env else _SOURCE.parent / "__pycache__"
    return [first, _user_cache() / "native"]


def _file_name(name: str, key: tuple) -> str:
    """One file per kernel, argument types, Python and CPU: rebuilt in place when anything else changes."""
    stamp = _stamp()
    which = _digest(repr((key, stamp["python"], stamp["cpu"])).encode())[:16]
    return f"_numba_kernels.{name}.{which}.native"


# --- trust: only the user's own files ---------------------------------------------------------
class _Refused(Exception):
    """A file that is there but may not be trusted (the message says why)."""


def _say(level: int, message: str) -> None:
    """Log ``message`` once per process (a folder that is not ours is so for every kernel)."""
    said = _state.setdefault("said", set())
    if message not in said:
        said.add(message)
        _log.log(level, message)


@cache
def _private_group(gid: int) -> bool:
    """Whether group ``gid`` is the user's private group: the user's primary group, with no one else in it."""
    uid = os.getuid()
    try:
        me, group = pwd.getpwuid(uid), grp.getgrgid(gid)
    except KeyError:
        return False
    if me.pw_gid != gid or any(name != me.pw_name for name in group.gr_mem):
        return False
    return all(user.pw_uid == uid for user in pwd.getpwall() if user.pw_gid == gid)


def _unsafe(st: os.stat_result, *, above: bool = False) -> str | None:
    """Why someone other than the user or root could change what has status ``st``; None when no one can.

    ``above``: a folder above the one read from, which may be writable by others when it is
    sticky (others cannot rename or remove what is not theirs in it).
    """
    if st.st_uid not in (os.getuid(), 0):
        return f"owned by another user (uid {st.st_uid})"
    if above and st.st_mode & stat.S_ISVTX:
        return None
    if st.st_mode & stat.S_IWOTH:
        return "writable by others"
    if st.st_mode & stat.S_IWGRP and not _private_group(st.st_gid):
        return "writable by its group"
    return None


def _distrust(folder: Path) -> str | None:
    """Why the files in ``folder`` could be someone else's (it, or a folder above it up to ``/``, is not ours); None when they cannot."""
    if not hasattr(os, "getuid"):  # no POSIX owners and modes (Windows): the checksum alone
        return None
    real = Path(os.path.realpath(folder))
    for at in (real, *real.parents):
        try:
            why = _unsafe(os.stat(at), above=at != real)
        except OSError as exc:
            return f"{at} cannot be checked ({exc.strerror})"
        if why is not None:
            return f"{at} is {why}"
    return None


def _read_ours(path: Path, *, private: bool = False) -> bytes:
    """The bytes of ``path`` when it is a regular file of ours, not a symbolic link; raises :class:`_Refused` otherwise.

    ``private``: readable by the user alone too (a secret). A missing file raises
    FileNotFoundError; a FIFO or device is refused without blocking.
    """
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_NONBLOCK", 0))
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            raise _Refused("it is a symbolic link") from None
        raise
    with os.fdopen(fd, "rb") as f:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            raise _Refused("it is not a regular file")
        why = _unsafe(st) if hasattr(os, "getuid") else None
        if why is None and private and st.st_mode & 0o077:
            why = f"readable by others (mode {stat.S_IMODE(st.st_mode):o}, not 600)"
        if why is not None:
            raise _Refused(f"it is {why}")
        if st.st_size > _LARGEST:
            raise _Refused(f"it is larger than {_LARGEST} bytes")
        return f.read(_LARGEST + 1)


def _make_folder(folder: Path) -> None:
    """Make ``folder`` and the folders above it that are missing, writable by the user alone whatever the umask."""
    missing = []
    while not folder.exists():
        missing.append(folder)
        folder = folder.parent
    for at in reversed(missing):
        try:
            os.mkdir(at, 0o755)  # the umask only takes bits away
        except FileExistsError:
            pass


def _write_new(path: Path, data: bytes, mode: int) -> None:
    """Write a new file whole and sync it (no symbolic link followed, nothing replaced)."""
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_NOFOLLOW", 0), mode)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
    except BaseException:
        path.unlink(missing_ok=True)
        raise


def _new_key(path: Path, *, replace: bool) -> bytes:
    """Make the user's secret at ``path`` (mode 0600, written whole); the one another process has just made, if any."""
    key = secrets.token_bytes(32)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.{threading.get_ident()}.tmp")
    _write_new(tmp, key, 0o600)
    try:
        if replace:
            os.replace(tmp, path)
        else:
            os.link(tmp, path)  # never over a key another process has just made
    except FileExistsError:
        return _read_ours(path, private=True)
    finally:
        tmp.unlink(missing_ok=True)
    return key


def _key() -> bytes | None:
    """The user's secret that signs the stored kernels, made on first use; None when it cannot be kept where only the user reaches it."""
    path = _user_cache() / "native.key"
    known = _state.get("key")
    if known is not None and known[0] == path:
        return known[1]
    try:
        _make_folder(path.parent)
        why = _distrust(path.parent)
        if why is not None:
            _say(logging.DEBUG, f"stored kernels not used: the folder of their key {why}")
            return None
        try:
            key = _read_ours(path, private=True)
            bad = None if len(key) == 32 else f"it has {len(key)} bytes, not 32"
        except FileNotFoundError:
            key, bad = b"", None
        except _Refused as exc:
            key, bad = b"", str(exc)
        if bad is not None:
            _say(logging.WARNING, f"the key of the stored kernels {path} is made anew: {bad}")
        if bad is not None or not key:
            key = _new_key(path, replace=bad is not None)
    except (OSError, _Refused) as exc:
        _say(logging.DEBUG, f"stored kernels not used: no key in {path.parent} ({exc})")
        return None
    _state["key"] = (path, key)
    return key


def _signer(key: bytes) -> str:
    """Which key signed a file (public: a digest of the key), to tell another key from an altered file."""
    return _digest(b"omniwidget native signer" + key)[:16]


# --- stored files ---------------------------------------------------------------------------------
def _unpack(path: Path, data: bytes, want: dict) -> tuple[dict, bytes] | None:
    """The header and machine code of a stored file that fits ``want`` and whose HMAC is right; None otherwise."""
    start = len(_MAGIC) + 4
    if not data.startswith(_MAGIC) or len(data) < start + _TAG:
        return None
    (size,) = struct.unpack_from("<I", data, len(_MAGIC))
    try:
        header = json.loads(data[start : start + size])
    except (ValueError, RecursionError):
        return None
    if not isinstance(header, dict) or any(header.get(k) != v for k, v in want.items()):
        return None  # built for another source, numba, CPU or format: rebuilt without a word, as before
    key = _key()
    if key is None:
        return None
    if header.get("signer") != _signer(key):
        _say(logging.DEBUG, f"stored kernel {path} not used: signed with another key (compiled again)")
        return None
    if not hmac.compare_digest(hmac.new(key, data[:-_TAG], hashlib.sha256).digest(), data[-_TAG:]):
        _say(logging.WARNING, f"stored kernel {path} not used: its checksum does not match, it was altered (compiled again)")
        return None
    return header, data[start + size : -_TAG]


def _read(name: str, key: tuple) -> tuple[dict, bytes] | None:
    """The stored kernel's header and machine code, when a file of ours fits this process; else None."""
    want = {**_stamp(), "kernel": name, "key": repr(key)}
    file_name = _file_name(name, key)
    for folder in _folders():
        path = folder / file_name
        if not folder.is_dir():
            continue
        why = _distrust(folder)
        if why is not None:
            _say(logging.DEBUG, f"stored kernels in {folder} not used: {why}")
            continue
        try:
            stored = _unpack(path, _read_ours(path), want)
        except FileNotFoundError:
            continue
        except (OSError, _Refused) as exc:
            _say(logging.WARNING, f"stored kernel {path} not used: {exc} (compiled again)")
            continue
        if stored is not None:
            return stored
    return None


def _write(name: str, key: tuple, header: dict, code: bytes) -> Path | None:
    """Store a kernel whole and signed (temporary file and rename) in the first folder of ours that can be written."""
    secret = _key()
    if secret is None:
        return None
    payload = json.dumps({**header, "signer": _signer(secret)}, sort_keys=True).encode()
    body = _MAGIC + struct.pack("<I", len(payload)) + payload + code
    data = body + hmac.new(secret, body, hashlib.sha256).digest()
    for folder in _folders():
        try:
            _make_folder(folder)
            why = _distrust(folder)
            if why is not None:
                _say(logging.DEBUG, f"stored kernels in {folder} not used: {why}")
                continue
            path = folder / _file_name(name, key)
            tmp = folder / f".{path.name}.{os.getpid()}.{threading.get_ident()}.tmp"
            _write_new(tmp, data, 0o644)
            try:
                os.replace(tmp, path)
            finally:
                tmp.unlink(missing_ok=True)
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
        binding.initialize_native_target()
        binding.initialize_native_asmprinter()
        ll = _state["llvm"] = resolve(binding)
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
    types, from_dtype = numba.types, numpy_support.from_dtype
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
    namespace = {"kernel": dispatcher, "carray": numba.carray}
    exec(f"def {name}_native({', '.join(params)}):\n    kernel({', '.join(call)})\n", namespace)  # noqa: S102
    # a C callback is always compiled in nopython mode; Any: numba's private _library below is in no stub
    compiled: Any = numba.cfunc(types.void(*argtypes))(namespace[f"{name}_native"])
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


# --- numba's own cache ----------------------------------------------------------------------------
def _distrust_numba_files(folder: Path) -> str | None:
    """Why numba's files of the kernels in ``folder`` (its pickled index and data) could be someone else's; None when none can."""
    try:
        entries = list(os.scandir(folder))
    except FileNotFoundError:
        return None
    except OSError as exc:
        return f"{folder} cannot be read ({exc.strerror})"
    for entry in entries:
        if entry.name.startswith("_numba_kernels.") and entry.name.endswith((".nbi", ".nbc")):
            st = entry.stat(follow_symlinks=False)
            why = "a symbolic link" if stat.S_ISLNK(st.st_mode) else _unsafe(st)
            if why is not None:
                return f"{entry.path} is {why}"
    return None


def _distrust_numba(dispatchers: list[Any]) -> str | None:
    """Why the folders numba caches ``dispatchers`` in, or their files, could be someone else's; None when they cannot."""
    folders: set[str] = {d._cache._cache_path for d in dispatchers if hasattr(d._cache, "_cache_path")}
    for folder in sorted(folders):
        why = _distrust(Path(folder)) or _distrust_numba_files(Path(folder))
        if why is not None:
            return why
    return None


def secure_numba_cache(namespace: dict[str, Any]) -> None:
    """Keep numba's cache of the kernels in ``namespace`` in a folder of the user's own, as the stored kernels are.

    Numba unpickles its index files (``.nbi``), and unpickling can run any code, so its cache
    folder must be no one else's either. Called on the kernels of :mod:`omniwidget._numba_kernels`
    when this module first imports them, before any of them runs (numba reads its cache at a kernel's first
    call). When the folder numba chose (``NUMBA_CACHE_DIR``, the package's ``__pycache__`` or
    numba's user cache), a folder above it or one of the kernels' files there is not ours (the
    rule of :func:`_distrust`), the kernels are cached in ``omniwidget/numba`` of the user's
    cache folder instead, or not at all when that is not ours either (numba compiles them in
    every process); why is logged once at debug level.
    """
    dispatchers = [d for d in namespace.values() if hasattr(d, "enable_caching") and hasattr(d, "_cache")]
    why = _distrust_numba(dispatchers)
    if why is None:
        return
    config: Any = importlib.import_module("numba.core.config")  # its settings are set at import: in no stub

    target = _user_cache() / "numba"
    try:
        _make_folder(target)
        instead = _distrust(target)
    except OSError as exc:
        instead = f"{target} cannot be made ({exc.strerror})"
    if instead is None:
        before = config.CACHE_DIR
        config.CACHE_DIR = str(target)  # read when a dispatcher's cache is made, so for these kernels alone
        try:
            for d in dispatchers:
                d.enable_caching()
            instead = _distrust_numba(dispatchers)  # numba makes its subfolder there with the umask
        except Exception as exc:  # noqa: BLE001 - no cache then, never a kernel that cannot run
            instead = f"numba cannot cache there ({exc})"
        finally:
            config.CACHE_DIR = before
    if instead is not None:
        for d in dispatchers:
            d._cache = caching.NullCache()
        _say(logging.DEBUG, f"numba's cache of the kernels is not used: {why}; nor {target}: {instead} (compiled in every process)")
    else:
        _say(logging.DEBUG, f"numba's cache of the kernels is not used: {why}; it is kept in {target} instead")


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


def _numba_module() -> Any:
    """:mod:`omniwidget._numba_kernels`, its numba cache made safe (:func:`secure_numba_cache`) before any kernel of it runs."""
    with _lock:
        module = resolve(_numba_kernels)
        if not _state.get("numba cache checked"):
            secure_numba_cache(vars(module))
            _state["numba cache checked"] = True
    return module


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
        dispatcher = getattr(_numba_module(), self.__name__)
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

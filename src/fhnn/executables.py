"""Compiled programs kept on disk as exported StableHLO, so that a later process runs them untraced.

JAX's persistent compilation cache (:func:`fhnn.runtime.use_compilation_cache`) keeps the XLA
compilation of a program, not its tracing and lowering: a new process still traces and lowers a
program before the cache can serve it (FHNN's Adam step: ~1.8 s of a new process's first step,
``benchmarks/training_speed.py``). :class:`StoredProgram` wraps an ``eqx.filter_jit`` function. Its
first call for an argument signature exports the function over the arguments' arrays
(:mod:`jax.export`: the lowered StableHLO module and its calling convention) and writes it to
``executables/`` in the compilation cache folder, under a key of everything that fixes the program:
the package's source, the versions of JAX and jaxlib, the backend and device, ``XLA_FLAGS``, the
function, the structure of the arguments, every non-array argument (static fields, configuration,
functions by name and bytecode) and the shape and dtype of every array. Every process — the one
that wrote the file and every later one — runs the exported module, compiled ahead of time over the
arrays; its XLA compilation is served by JAX's persistent cache, so a later process neither traces
the function nor compiles it (~0.8 s). Results are therefore the same bits in every process.
The trainer's programs, rollouts (:meth:`fhnn.models.base.AbstractVectorField.solve`) and
simulations (:func:`fhnn.data.simulate.integrate`) are stored programs.
(A function's own bytecode is hashed, not that of functions it calls from outside this package:
after changing such a function, delete ``executables/``.)

Arrays are the program's arguments; everything else is part of the key. The wrapped function is
called as it is — no file written or read — when no compilation cache folder is set, inside a
traced program, when a signature cannot be keyed (a non-array argument that cannot be pickled, a
function with a closure), when its output holds a function made inside it, or when it cannot be
exported (host callbacks, such as Equinox's runtime checks under ``EQX_ON_ERROR=raise``:
:mod:`fhnn.runtime`).
A stored file that cannot be read or compiled is deleted and the program exported again.

(Why exported modules and not serialized executables: design note ``docs/design/layout.md``.)
"""

from __future__ import annotations

import hashlib
import inspect
import io
import itertools
import logging
import os
import pickle
import types
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import equinox as eqx
import jax
import jaxlib
from jax import export as jax_export

from fhnn.files import write_atomic
from fhnn.runtime import source_digest

logger = logging.getLogger(__name__)

#: Folder, inside the compilation cache folder, of the stored executables.
FOLDER = "executables"
#: Changes whenever what a stored file holds or how keys are made changes.
_FORMAT = b"fhnn-exported-1"
_PRIMITIVE = (int, float, complex, str, bytes, bool, type(None))


class _Unkeyable(Exception):
    """An argument or output that has no stable identity across processes."""


def _code_fingerprint(code: types.CodeType, h: Any) -> None:
    """Feed ``code``'s bytecode, names and constants (nested code objects included) into ``h``."""
    h.update(code.co_code)
    h.update(repr((code.co_names, code.co_varnames, code.co_freevars)).encode())
    for const in code.co_consts:
        if isinstance(const, types.CodeType):
            _code_fingerprint(const, h)
        else:
            h.update(repr(const).encode())


def _is_function(obj: Any) -> bool:
    """A function (plain, builtin, or a wrapper of one such as a jitted function), as opposed to
    a callable object with fields (an Equinox module), which is pickled by value."""
    if isinstance(obj, (types.FunctionType, types.BuiltinFunctionType)):
        return True
    return callable(obj) and hasattr(obj, "__wrapped__") and not isinstance(obj, (type, eqx.Module))


def _function_id(obj: Any) -> tuple[str, ...]:
    """What names a function across processes: its module, qualified name and, for a Python
    function, a hash of its code (which tells two lambdas of one scope apart). A closure (its
    cells' values are not in the key) or a nameless callable: :class:`_Unkeyable`."""
    name = getattr(obj, "__qualname__", None)
    if not isinstance(name, str):
        raise _Unkeyable(f"function {obj!r} has no name")
    module = str(getattr(obj, "__module__", None))
    if isinstance(obj, types.FunctionType):
        if obj.__closure__:
            raise _Unkeyable(f"function {name} has a closure")
        h = hashlib.sha256()
        _code_fingerprint(obj.__code__, h)
        return ("function", module, name, h.hexdigest())
    return ("callable", module, name)


class _KeyPickler(pickle.Pickler):
    """Pickles a signature's non-array part the same way in every process: functions by
    :func:`_function_id`, everything else by value. Every non-primitive object it meets is kept
    in :attr:`seen`, in order, so an output can refer to an input's objects (:class:`_OutPickler`)."""

    def __init__(self, file: io.BytesIO) -> None:
        super().__init__(file, protocol=5)
        # no memo: an object met twice is written twice, so the bytes depend on the values only,
        # not on which of them happen to be one object (an output read from disk is a copy)
        self.fast = True
        self.seen: list[Any] = []

    def persistent_id(self, obj: Any) -> Any:
        if isinstance(obj, _PRIMITIVE):
            return None
        self.seen.append(obj)
        if _is_function(obj):
            return _function_id(obj)
        return None


class _OutPickler(pickle.Pickler):
    """Pickles an output's non-array part, writing an object that is one of the inputs' (by
    identity) as its index in :attr:`_KeyPickler.seen`."""

    def __init__(self, file: io.BytesIO, seen: list[Any]) -> None:
        super().__init__(file, protocol=5)
        self.index = {id(obj): k for k, obj in enumerate(seen)}

    def persistent_id(self, obj: Any) -> Any:
        if isinstance(obj, _PRIMITIVE):
            return None
        k = self.index.get(id(obj))
        if k is not None:
            return ("input", k)
        if _is_function(obj):
            raise _Unkeyable(f"output holds a function made by the program: {obj!r}")
        return None


class _OutUnpickler(pickle.Unpickler):
    """Reads what :class:`_OutPickler` wrote, resolving input references against ``seen``."""

    def __init__(self, file: io.BytesIO, seen: list[Any]) -> None:
        super().__init__(file)
        self.seen = seen

    def persistent_load(self, pid: Any) -> Any:
        return self.seen[pid[1]]


@dataclass(frozen=True)
class _Program:
    """A compiled program over the array arguments, and how to rebuild its output: the output's
    tree, which of its leaves are arrays (the program's outputs, in order) and the others."""

    compiled: Callable[..., list[Any]]
    out_tree: Any
    out_mask: tuple[bool, ...]
    out_others: tuple[Any, ...]

    def __call__(self, arrays: list[Any]) -> Any:
        leaves = _merge(self.out_mask, self.compiled(*arrays), self.out_others)
        return jax.tree.unflatten(self.out_tree, leaves)


def _split(tree: Any) -> tuple[Any, tuple[bool, ...], list[Any], tuple[Any, ...]]:
    """``tree``'s structure, which leaves are arrays, the arrays and the other leaves."""
    leaves, structure = jax.tree.flatten(tree)
    mask = tuple(map(eqx.is_array, leaves))
    arrays = [x for x, m in zip(leaves, mask, strict=True) if m]
    others = tuple(x for x, m in zip(leaves, mask, strict=True) if not m)
    return structure, mask, arrays, others


def _merge(mask: tuple[bool, ...], arrays: Any, others: tuple[Any, ...]) -> list[Any]:
    """The leaves :func:`_split` took apart, in order."""
    arrays, others_ = iter(arrays), iter(others)
    return [next(arrays) if m else next(others_) for m in mask]


def _environment() -> bytes:
    """What besides the program fixes its executable: package source, versions, device, flags."""
    device = jax.devices()[0]
    parts = (
        source_digest((".",)),
        jax.__version__,
        jaxlib.__version__,
        device.platform,
        device.device_kind,
        device.client.platform_version,
        os.environ.get("XLA_FLAGS", ""),
    )
    return repr(parts).encode()


#: Environment variable that turns the store off ("off": every program is traced and compiled as
#: ``eqx.filter_jit`` does, with JAX's persistent cache alone).
STORE_ENV = "FHNN_EXECUTABLES"


def store_folder() -> Path | None:
    """``executables/`` in JAX's compilation cache folder, or ``None`` when no folder is set or
    ``$FHNN_EXECUTABLES`` is "off"."""
    if os.environ.get(STORE_ENV, "").strip().lower() == "off":
        return None
    cache = jax.config.jax_compilation_cache_dir
    return Path(cache) / FOLDER if cache else None


#: Programs made or loaded in this process, by signature: a second job of the same signature
#: (an ensemble's next member) reuses them with no file read. ``None``: the signature cannot be
#: keyed or exported (it is called as it is, without trying again).
_MEMO: dict[Any, _Program | None] = {}


class StoredProgram:
    """``fn`` (an ``eqx.filter_jit`` function) whose compiled executables are kept on disk, one
    per argument signature, in :func:`store_folder`; see the module's text.

    Calling it returns what ``fn`` returns, bitwise. :attr:`loaded` counts the executables read
    from disk and :attr:`stored` those compiled and written by this object.

    ``donate`` names positional arguments whose arrays the compiled program may overwrite with its
    outputs (XLA buffer donation): after a call those arrays are deleted, so pass only arguments
    the caller replaces by the output, as an optimiser's state in a loop. It saves copying them —
    an L-BFGS state of 100 pairs is ~7 MB, copied on every iteration without it — and changes no
    bit of the result. It applies to the stored program only; where ``fn`` is called as it is
    (see the module's text), nothing is donated."""

    def __init__(self, fn: Callable[..., Any], donate: tuple[int, ...] = ()) -> None:
        self.fn = fn
        self.donate = tuple(sorted(set(donate)))
        self.name = f"{getattr(fn, '__module__', '')}.{getattr(fn, '__qualname__', repr(fn))}"
        try:  # the function's identity across processes (a closure has none: never stored)
            self._identity: tuple[str, ...] | None = _function_id(inspect.unwrap(fn))
        except _Unkeyable:
            self._identity = None
        self.loaded = 0
        self.stored = 0
        self._last: tuple[Any, _Program | None] | None = None

    def __call__(self, *args: Any) -> Any:
        folder = store_folder()
        if folder is None or self._identity is None:
            return self.fn(*args)
        tree, mask, arrays, others = _split(args)
        if any(isinstance(x, jax.core.Tracer) for x in arrays):  # called inside a traced program
            return self.fn(*args)
        avals = tuple((x.shape, x.dtype, getattr(x, "weak_type", False)) for x in arrays)
        signature = (self.fn, tree, mask, others, avals, self.donate)
        if self._last is not None and self._last[0] == signature:
            program = self._last[1]
        else:
            try:
                hash(signature)
            except TypeError:
                program = None
            else:
                if signature in _MEMO:
                    program = _MEMO[signature]
                else:
                    program = _MEMO[signature] = self._prepare(folder, signature, arrays)
            self._last = (signature, program)
        return self.fn(*args) if program is None else program(arrays)

    def _prepare(self, folder: Path, signature: tuple, arrays: list[Any]) -> _Program | None:
        """The program of ``signature``: read from ``folder``, else compiled and written there;
        ``None`` when the signature cannot be keyed."""
        buffer = io.BytesIO()
        pickler = _KeyPickler(buffer)
        try:
            pickler.dump((self._identity, *signature[1:5]))
        except (_Unkeyable, pickle.PicklingError, TypeError, AttributeError) as err:
            logger.debug("%s is called unstored: %s", self.name, err)
            return None
        key = hashlib.sha256(_FORMAT + _environment() + buffer.getvalue()).hexdigest()[:32]
        path = folder / f"{self.name.rsplit('.', 1)[-1]}-{key}.bin"
        donated = _donated(signature[1], signature[2], self.donate)
        program = self._load(path, arrays, donated, pickler.seen)
        if program is None:
            program = self._compile(path, signature, arrays, donated, pickler.seen)
        return program

    def _load(
        self, path: Path, arrays: list[Any], donated: tuple[int, ...], seen: list[Any]
    ) -> _Program | None:
        """The program stored at ``path``, compiled over ``arrays`` (those at ``donated``
        donated); ``None`` (and the file deleted) when it is missing, unreadable or does not
        compile for them."""
        if not path.is_file():
            return None
        try:
            module, out_part = pickle.loads(path.read_bytes())
            exported = jax_export.deserialize(bytearray(module))
            out_tree, out_mask, out_others = _OutUnpickler(io.BytesIO(out_part), seen).load()
            program = _Program(_compiled(exported, arrays, donated), out_tree, out_mask, out_others)
        except Exception as err:  # a stale or damaged file only costs a compilation
            logger.warning("discarding stored executable %s: %s", path.name, err)
            path.unlink(missing_ok=True)
            return None
        self.loaded += 1
        return program

    def _compile(
        self, path: Path, signature: tuple, arrays: list[Any], donated: tuple[int, ...], seen: list[Any]
    ) -> _Program | None:
        """Export the program of ``signature``, write it to ``path`` and compile it (the arrays at
        ``donated`` donated); ``None`` when it cannot be exported or its output cannot be written
        (the function is then called as it is)."""
        _, tree, mask, others, _, _ = signature
        made: list[Any] = []

        def flat(*inputs: Any) -> list[Any]:
            out_tree, out_mask, out_arrays, out_others = _split(
                self.fn(*jax.tree.unflatten(tree, _merge(mask, inputs, others)))
            )
            made[:] = [out_tree, out_mask, out_others]
            return out_arrays

        flat.__name__ = flat.__qualname__ = f"stored_{self.name.rsplit('.', 1)[-1]}"
        try:
            exported = jax_export.export(jax.jit(flat))(*arrays)
            buffer = io.BytesIO()
            _OutPickler(buffer, seen).dump(tuple(made))
            data = pickle.dumps((bytes(exported.serialize()), buffer.getvalue()), protocol=5)
        except Exception as err:  # host callbacks, unpicklable outputs: called unstored
            logger.debug("%s is not stored: %s", self.name, err)
            return None
        program = _Program(_compiled(exported, arrays, donated), *made)
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            write_atomic(path, data)
        except OSError as err:  # the store only saves time
            logger.warning("could not store executable %s: %s", path.name, err)
            return program
        self.stored += 1
        return program


def _donated(tree: Any, mask: tuple[bool, ...], donate: tuple[int, ...]) -> tuple[int, ...]:
    """Positions, among the arrays :func:`_split` takes from the arguments (structure ``tree``,
    array leaves ``mask``), of the arrays of the arguments ``donate`` names. Worked out once per
    signature, not per call."""
    arrays_before = [0, *itertools.accumulate(mask)]  # arrays among the leaves before each leaf
    out, leaf = [], 0
    for i, arg in enumerate(tree.children()):
        if i in donate:
            out.extend(range(arrays_before[leaf], arrays_before[leaf + arg.num_leaves]))
        leaf += arg.num_leaves
    return tuple(out)


def _compiled(
    exported: jax_export.Exported, arrays: list[Any], donated: tuple[int, ...] = ()
) -> Callable[..., list[Any]]:
    """``exported``'s module compiled ahead of time over ``arrays`` (through JAX's persistent
    cache), the arrays at positions ``donated`` donated to its outputs. A compiled program takes
    arrays committed to a device or not alike, so an output fed back as the next call's input
    never compiles it again."""
    return jax.jit(exported.call, donate_argnums=donated).lower(*arrays).compile()


__all__ = ["FOLDER", "STORE_ENV", "StoredProgram", "store_folder"]

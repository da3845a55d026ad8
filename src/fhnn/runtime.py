"""Process-wide settings, in one place: the package version, float64, Equinox's runtime checks, GPU
memory allocated as needed (:data:`XLA_PREALLOCATE_DEFAULT`) and the compilation cache.

JAX's settings are global to a process. Importing :mod:`fhnn` (which imports this module first)
switches JAX to float64, so every computation of the package runs in double precision, and, unless
``$EQX_ON_ERROR`` is set, sets it to ``nan`` before Equinox is imported
(:data:`EQX_ON_ERROR_DEFAULT`);
:func:`use_compilation_cache` points JAX's persistent compilation cache at a folder, so a program
compiled once (a training step, a rollout) is loaded, not compiled again, by later jobs and
processes that share the folder. Every ``fhnn`` command uses the folder
:func:`default_cache_dir` names (``$FHNN_JAX_CACHE``; by default ``~/.cache/fhnn/jax``): a second
run of the same shapes then loads its training step, rollouts and simulations instead of compiling
them — untraced, from the executables :mod:`fhnn.executables` keeps in the same folder
(``benchmarks/training_speed.py`` times both).
"""

from __future__ import annotations

import functools
import hashlib
import os
from importlib import metadata as _metadata
from pathlib import Path

#: Equinox's runtime checks (``eqx.error_if``: Diffrax checks a solve's output times with them)
#: call back into Python from compiled code when ``$EQX_ON_ERROR`` is ``raise``, Equinox's default,
#: and JAX neither caches nor exports a program that calls back: every process compiled every
#: rollout and simulation again. With ``nan`` a failed check gives NaN instead, which the rollouts
#: report as a failed trajectory (:func:`fhnn.physics.integrators.adaptive_solve`); fhnn's own code
#: makes no such check, and its training programs hold none. Set only where the variable is unset,
#: and effective only where Equinox is not imported yet (the rollouts then compile in each process).
EQX_ON_ERROR_DEFAULT = "nan"
os.environ.setdefault("EQX_ON_ERROR", EQX_ON_ERROR_DEFAULT)

#: On a GPU, JAX takes 75 % of the device's memory when a process first uses it, so a second process
#: on the same GPU (``fhnn reproduce``'s workers, runs side by side) starts short of memory: three
#: FHNN trainings at once on an H100 logged failed allocations and failed cuBLAS handles. fhnn's
#: programs need a few hundred MB, so each process allocates what it uses instead. Set only where
#: ``$XLA_PYTHON_CLIENT_PREALLOCATE`` is unset; no effect on a CPU.
XLA_PREALLOCATE_DEFAULT = "false"
os.environ.setdefault("XLA_PYTHON_CLIENT_PREALLOCATE", XLA_PREALLOCATE_DEFAULT)

import jax  # noqa: E402  (after the Equinox setting, which Equinox reads once, on import)

jax.config.update("jax_enable_x64", True)

try:
    __version__ = _metadata.version("fhnn")
except _metadata.PackageNotFoundError:  # running from a source tree that is not installed
    __version__ = "0.0.0+unknown"


def use_compilation_cache(cache_dir: str | None) -> None:
    """Point JAX's persistent compilation cache at ``cache_dir`` (every entry kept); no-op for
    ``None`` or an empty string."""
    if not cache_dir:
        return
    jax.config.update("jax_compilation_cache_dir", cache_dir)
    jax.config.update("jax_persistent_cache_min_entry_size_bytes", -1)
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0)


#: Environment variable naming the commands' compilation cache folder ("" or "off": no cache).
CACHE_ENV = "FHNN_JAX_CACHE"


def default_cache_dir() -> str | None:
    """The commands' compilation cache folder: ``$FHNN_JAX_CACHE`` when set (``None`` when it is
    empty or "off"), else ``$XDG_CACHE_HOME/fhnn/jax`` or ``~/.cache/fhnn/jax``; ``None`` when the
    folder cannot be created (the cache only saves time)."""
    value = os.environ.get(CACHE_ENV)
    if value is not None and value.strip().lower() in ("", "off"):
        return None
    if value is None:
        base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
        value = os.path.join(base, "fhnn", "jax")
    try:
        os.makedirs(value, exist_ok=True)
    except OSError:
        return None
    return value if os.access(value, os.W_OK) else None


#: The installed package's folder (holding ``physics/``, ``data/``, ...).
PACKAGE_ROOT = Path(__file__).resolve().parent


def _code(text: str) -> str:
    """The syntax tree of Python source ``text`` without docstrings (any statement that is a bare
    string, which does nothing), as text; comments and layout are not in the tree."""
    import ast

    def doc(stmt: ast.stmt) -> bool:
        return (
            isinstance(stmt, ast.Expr)
            and isinstance(stmt.value, ast.Constant)
            and isinstance(stmt.value.value, str)
        )

    tree = ast.parse(text)
    for node in ast.walk(tree):
        for name in ("body", "orelse", "finalbody"):
            block = getattr(node, name, None)
            if isinstance(block, list) and block and isinstance(block[0], ast.stmt):
                setattr(node, name, [s for s in block if not doc(s)] or [ast.Pass()])
    return ast.dump(tree, include_attributes=False)


@functools.cache
def source_digest(parts: tuple[str, ...], root: Path | None = None) -> str:
    """A hash (16 hex digits) of the package's code: the relative path and syntax tree, without
    docstrings and comments, of every ``.py`` file under ``parts`` (folders or files relative to
    ``root``, default :data:`PACKAGE_ROOT`), in sorted order. What a cached result was computed
    by: a change to the code of any of these files changes it, a change to their documentation
    does not. Read once per process."""
    base = PACKAGE_ROOT if root is None else Path(root)
    files: set[Path] = set()
    for part in parts:
        path = base / part
        if path.is_dir():
            files.update(path.rglob("*.py"))
        elif path.is_file():
            files.add(path)
        else:
            raise FileNotFoundError(f"no source {part!r} under {base}")
    h = hashlib.sha256()
    for path in sorted(files):
        h.update(path.relative_to(base).as_posix().encode() + b"\0")
        h.update(_code(path.read_text()).encode() + b"\0")
    return h.hexdigest()[:16]


#: The package's parts whose code can move a result (all but the command line's shell).
RESULT_SOURCES = (
    "physics",
    "data",
    "models",
    "training",
    "evaluation",
    "experiments",
    "api",
    "config.py",
    "executables.py",
    "files.py",
    "runtime.py",
)
#: Packages whose versions a result records.
RESULT_PACKAGES = ("jax", "jaxlib", "equinox", "optax", "diffrax", "optimistix", "lineax", "numpy", "scipy")


def _git(*args: str) -> str | None:
    import subprocess

    try:
        done = subprocess.run(
            ["git", *args], cwd=PACKAGE_ROOT, capture_output=True, text=True, timeout=30, check=True
        )
    except (OSError, subprocess.SubprocessError):
        return None
    return done.stdout.strip()


def _cpu_model() -> str:
    import platform

    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def provenance() -> dict[str, object]:
    """What made a result, for the files results are written to.

    Returns:
        ``version`` (fhnn's), ``commit`` and ``dirty`` (whether the package's source differs
        from it; both ``None`` outside a git work tree), ``source`` (:func:`source_digest` of
        :data:`RESULT_SOURCES`: equal digests, equal results-affecting code), ``python`` and
        ``packages`` (versions of :data:`RESULT_PACKAGES`), ``machine`` (CPU model, cores, JAX's
        device) and ``date`` (UTC, ISO 8601).
    """
    import datetime
    import platform

    packages = {}
    for name in RESULT_PACKAGES:
        try:
            packages[name] = _metadata.version(name)
        except _metadata.PackageNotFoundError:
            packages[name] = None
    commit = _git("rev-parse", "HEAD")
    status = _git("status", "--porcelain", "--", ".") if commit else None
    return {
        "version": __version__,
        "commit": commit,
        "dirty": None if status is None else bool(status),
        "source": source_digest(RESULT_SOURCES),
        "python": platform.python_version(),
        "packages": packages,
        "machine": {"cpu": _cpu_model(), "cores": os.cpu_count(), "device": jax.devices()[0].device_kind},
        "date": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
    }


__all__ = [
    "CACHE_ENV",
    "PACKAGE_ROOT",
    "RESULT_SOURCES",
    "__version__",
    "default_cache_dir",
    "provenance",
    "source_digest",
    "use_compilation_cache",
]

"""Process-wide settings, in one place: the package version, float64 and the compilation cache.

JAX's settings are global to a process. Importing :mod:`fhnn` (which imports this module first)
switches JAX to float64, so every computation of the package runs in double precision;
:func:`use_compilation_cache` points JAX's persistent compilation cache at a folder, so a program
compiled once (a training step, a rollout) is loaded, not compiled again, by later jobs and
processes that share the folder.
"""

from __future__ import annotations

from importlib import metadata as _metadata

import jax

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


__all__ = ["__version__", "use_compilation_cache"]

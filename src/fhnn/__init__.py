"""fhnn — Floating-Body Hydrodynamic Neural Networks.

Physics-structured system identification of floating bodies: from trajectories of a body drifting
in a 2-D incompressible flow, learn the background flow (as a stream function), the added masses and
the linear and quadratic drag, and predict long horizons stably.

Importing :mod:`fhnn` switches JAX to float64 (a process-global setting): every computation in
this package is carried out in double precision unless a user asks otherwise.
"""

from importlib import metadata as _metadata

import jax as _jax

_jax.config.update("jax_enable_x64", True)

try:
    __version__ = _metadata.version("fhnn")
except _metadata.PackageNotFoundError:  # running from a source tree that is not installed
    __version__ = "0.0.0+unknown"

__all__ = ["__version__"]

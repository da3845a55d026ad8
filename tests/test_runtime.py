"""Process-wide settings of :mod:`fhnn.runtime`: defaults for JAX's and Equinox's environment
variables, set only where the user left them unset."""

from __future__ import annotations

import os
import subprocess
import sys

SHOW = (
    "import os, fhnn.runtime; print(os.environ['EQX_ON_ERROR'], os.environ['XLA_PYTHON_CLIENT_PREALLOCATE'])"
)


def _settings(**env: str) -> list[str]:
    clean = {
        k: v for k, v in os.environ.items() if k not in ("EQX_ON_ERROR", "XLA_PYTHON_CLIENT_PREALLOCATE")
    }
    done = subprocess.run(
        [sys.executable, "-c", SHOW], env={**clean, **env}, capture_output=True, text=True, check=True
    )
    return done.stdout.split()


def test_importing_fhnn_sets_its_defaults_only_where_unset() -> None:
    # on a GPU, several fhnn processes share the device: none takes 75 % of its memory up front
    assert _settings() == ["nan", "false"]
    assert _settings(EQX_ON_ERROR="raise", XLA_PYTHON_CLIENT_PREALLOCATE="true") == ["raise", "true"]

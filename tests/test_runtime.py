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


def test_provenance_names_the_code_and_the_machine() -> None:
    from fhnn.runtime import PACKAGE_ROOT, RESULT_SOURCES, provenance, source_digest

    record = provenance()
    assert record["source"] == source_digest(RESULT_SOURCES)
    assert record["machine"]["cores"] == os.cpu_count() and record["machine"]["device"] == "cpu"
    assert record["packages"]["jax"] is not None and record["date"].endswith("+00:00")
    head = subprocess.run(["git", "rev-parse", "HEAD"], cwd=PACKAGE_ROOT, capture_output=True, text=True)
    if head.returncode == 0:  # a git checkout: the commit and whether the package differs from it
        assert record["commit"] == head.stdout.strip() and isinstance(record["dirty"], bool)
    else:
        assert record["commit"] is None and record["dirty"] is None


def test_source_digest_follows_the_code_not_its_documentation(tmp_path) -> None:
    """Docstrings, comments and layout leave the digest alone; a changed statement moves it."""
    from fhnn.runtime import source_digest

    def digest(text: str, name: str) -> str:
        folder = tmp_path / name
        (folder / "pkg").mkdir(parents=True)
        (folder / "pkg" / "m.py").write_text(text)
        return source_digest(("pkg",), folder)

    plain = digest("def f(x):\n    return 2 * x\n", "plain")
    documented = digest(
        '"""Module."""\n\n\ndef f(x):  # twice\n    """Twice ``x``."""\n    return 2 * x\n', "doc"
    )
    changed = digest("def f(x):\n    return 3 * x\n", "changed")
    assert plain == documented and plain != changed

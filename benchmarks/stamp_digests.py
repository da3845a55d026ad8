"""Add each file's digest to the stamps of result files made before stamps recorded them, or
check that every shown result's stamp is what the code at its commit gives.

    python benchmarks/stamp_digests.py              # every file in benchmarks/results lacking them
    python benchmarks/stamp_digests.py NAME ...     # benchmarks/results/NAME.json
    python benchmarks/stamp_digests.py --check      # audit every shown result's stamp

A stamp records ``source``, the digest of the code of its ``files``; since ``file_digests``
exists (:func:`fhnn.stamps.file_digests`), the benchmarks record each file's digest too, so a
result is judged only by the files its script runs (:func:`fhnn.stamps.stale_reason`). For an
older stamp this reads the package at the stamp's commit (``git archive``), checks that its code
gives the stamp's ``source`` over the stamp's ``files``, and only then adds the digests of those
files. A stamp from a changed work tree (``dirty``), or one whose commit does not give its
digest, is left as it is and named: it stays judged by all its files.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import tarfile
import tempfile
from pathlib import Path

from fhnn.runtime import source_digest
from fhnn.stamps import file_digests

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results"


def digests_at_commit(stamp: dict) -> dict[str, str]:
    """The digest of each of ``stamp["files"]`` at ``stamp["commit"]``.

    Raises:
        ValueError: the stamp is from a changed work tree, lacks ``files`` or ``commit``, or the
            code at its commit does not give its ``source``.
    """
    if stamp.get("dirty") is not False or not stamp.get("commit") or not stamp.get("files"):
        raise ValueError("made from a changed work tree, or without 'commit' or 'files'")
    with tempfile.TemporaryDirectory() as tmp:
        archive = Path(tmp) / "src.tar"
        subprocess.run(
            ["git", "archive", "-o", str(archive), stamp["commit"], "src/fhnn"], cwd=ROOT, check=True
        )
        with tarfile.open(archive) as tar:
            tar.extractall(tmp, filter="data")
        package = Path(tmp) / "src" / "fhnn"
        files = tuple(stamp["files"])
        found = source_digest.__wrapped__(files, package)
        if found != stamp["source"]:
            raise ValueError(f"the code at {stamp['commit'][:7]} gives {found}, not {stamp['source']}")
        return file_digests(list(files), package)


def add_digests(path: Path) -> str:
    """Add ``file_digests`` to the stamp of the result file ``path`` after its ``files``, the
    rest of the text unchanged; what was done, in words."""
    text = path.read_text()
    stamp = json.loads(text)["provenance"]
    if "file_digests" in stamp:
        return "has them"
    try:
        digests = digests_at_commit(stamp)
    except (ValueError, subprocess.CalledProcessError) as e:
        return f"left alone: {e}"
    at = text.index('"files": ', text.index('"provenance"')) + len('"files": ')
    _, length = json.JSONDecoder().raw_decode(text[at:])
    text = text[: at + length] + ', "file_digests": ' + json.dumps(digests) + text[at + length :]
    assert json.loads(text)["provenance"]["file_digests"] == digests
    path.write_text(text)
    return f"{len(digests)} digests added"


def audit(path: Path) -> str | None:
    """Why the stamp of the shown result file ``path`` is not what the package at its commit
    gives (its ``source`` over its ``files``, and each of its ``file_digests``), or ``None``
    when it is."""
    stamp = json.loads(path.read_text())["provenance"]
    try:
        digests = digests_at_commit(stamp)
    except (ValueError, subprocess.CalledProcessError) as e:
        return str(e)
    recorded = stamp.get("file_digests")
    if recorded is not None and recorded != digests:
        wrong = sorted(f for f in set(recorded) | set(digests) if recorded.get(f) != digests.get(f))
        return f"{len(wrong)} file digests differ from the code at its commit ({', '.join(wrong[:3])})"
    return None


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("names", nargs="*", help="result names (default: every result file)")
    p.add_argument(
        "--check",
        action="store_true",
        help="change nothing: check every shown result's stamp (the benchmarks' and the "
        "reproduction's) against the code at its commit; exit 1 if any differs",
    )
    args = p.parse_args()
    if args.check:
        import regenerate

        shown, failed = regenerate.shown_files(), 0
        for path in shown:
            reason = audit(path)
            failed += reason is not None
            print(f"{path.relative_to(ROOT)}: {reason or 'its commit gives its stamp'}")
        print(f"{failed} of {len(shown)} stamps differ from the code at their commit")
        raise SystemExit(1 if failed else 0)
    paths = [RESULTS / f"{n}.json" for n in args.names] or sorted(RESULTS.glob("*.json"))
    for path in paths:
        if not path.is_file():
            raise SystemExit(f"error: no result file {path.relative_to(ROOT)}")
        print(f"{path.stem}: {add_digests(path)}")


if __name__ == "__main__":
    main()

"""Whether a stamped result was made by the current code.

A result file's provenance (:func:`fhnn.runtime.provenance`) records ``source``, the digest of the
results-affecting code, and, since this module exists, ``files``: the results-affecting files that
digest covered (paths relative to :data:`fhnn.runtime.PACKAGE_ROOT`). A result is current while
those files exist and their code (syntax trees, documentation aside) still has that digest. A file
added after the result was made cannot have moved it: it reaches a result only through an
existing file that imports it, and that file's change makes the result stale (the package finds no
module by scanning; ``tests/test_results_current.py`` checks that). A stamp without ``files`` is
judged against every results-affecting file, as before.

A result whose stamp also records ``file_digests`` (the digest of each of those files' code) can
be judged by the files its script can run (:func:`import_closure`): it stays current while every
file its script reaches, through the imports written in the script and in the package, still has
the digest it was made with. A change elsewhere in the package cannot have moved it. The scripts
themselves are not stamped: a file the result was made without, which the script reaches now,
is reached through the script (or through a changed file, which makes it stale).
"""

from __future__ import annotations

import ast
import functools
import hashlib
from collections.abc import Mapping
from pathlib import Path

from fhnn.runtime import PACKAGE_ROOT, RESULT_SOURCES, _code


def result_files() -> list[str]:
    """The ``.py`` files under :data:`fhnn.runtime.RESULT_SOURCES`, relative to the package root,
    sorted: what :func:`fhnn.runtime.source_digest` of them covers."""
    return result_files_under(PACKAGE_ROOT)


def result_files_under(root: Path) -> list[str]:
    """:func:`result_files` of a package folder ``root``."""
    files: set[str] = set()
    for part in RESULT_SOURCES:
        path = root / part
        found = path.rglob("*.py") if path.is_dir() else [path] if path.is_file() else []
        files.update(p.relative_to(root).as_posix() for p in found)
    return sorted(files)


def file_digests(files: list[str], root: Path | None = None) -> dict[str, str]:
    """The digest (16 hex digits) of each file's code, its syntax tree without docstrings and
    comments, as :func:`fhnn.runtime.source_digest` reads it.

    Args:
        files: paths relative to ``root`` (default :data:`fhnn.runtime.PACKAGE_ROOT`).
    """
    base = PACKAGE_ROOT if root is None else Path(root)
    return {f: _digest((base / f).read_text()) for f in files}


def source_now(files: list[str] | tuple[str, ...], root: Path | None = None) -> str:
    """:func:`fhnn.runtime.source_digest` of ``files`` (paths relative to ``root``, default
    :data:`fhnn.runtime.PACKAGE_ROOT`) as they are now: that function reads the files once per
    process, so it would miss a change made after a first call; this one reads them every time
    (each text's syntax tree kept, as :func:`file_digests` keeps its digest)."""
    base = PACKAGE_ROOT if root is None else Path(root)
    h = hashlib.sha256()
    for path in sorted(base / f for f in files):
        h.update(path.relative_to(base).as_posix().encode() + b"\0")
        h.update(_syntax(path.read_text()).encode() + b"\0")
    return h.hexdigest()[:16]


@functools.cache
def _syntax(text: str) -> str:
    """:func:`fhnn.runtime._code` of source ``text``, kept per text."""
    return _code(text)


@functools.cache
def _digest(text: str) -> str:
    """:func:`file_digests`' digest of source ``text``; kept per text, since judging every shown
    result reads the same files again for each."""
    return hashlib.sha256(_syntax(text).encode()).hexdigest()[:16]


def _lazy_names(root: Path) -> dict[str, str]:
    """The package's lazy public names (``fhnn._PUBLIC``: name → module)."""
    for node in ast.parse((root / "__init__.py").read_text()).body:
        if isinstance(node, ast.Assign) and any(getattr(t, "id", None) == "_PUBLIC" for t in node.targets):
            return ast.literal_eval(node.value)
    return {}


def _module(name: str, root: Path) -> list[Path] | None:
    """The files importing module ``name`` (``fhnn`` or below) runs: its packages' ``__init__.py``
    and its own file; ``None`` when no such module is under ``root``."""
    parts = name.split(".")
    if parts[0] != "fhnn":
        return None
    folder, files = root, [root / "__init__.py"]
    for i, part in enumerate(parts[1:], start=2):
        if (folder / part / "__init__.py").is_file():
            folder = folder / part
            files.append(folder / "__init__.py")
        elif i == len(parts) and (folder / f"{part}.py").is_file():
            files.append(folder / f"{part}.py")
        else:
            return None
    return files


#: Calls that start a process: ``subprocess``'s and ``os``'s.
_PROCESS_MODULES = {"subprocess": None, "os": ("system", "popen", "exec", "spawn")}


def _starts_python(tree: ast.AST) -> bool:
    """Whether code starts Python processes of its own (``sys.executable`` anywhere; the ``fhnn``
    command or ``python`` in a call of ``subprocess`` or ``os``): what those run, its imports do
    not bound."""
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and node.attr == "executable":
            if isinstance(node.value, ast.Name) and node.value.id == "sys":
                return True
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute):
            owner = node.func.value
            if not isinstance(owner, ast.Name) or owner.id not in _PROCESS_MODULES:
                continue
            names = _PROCESS_MODULES[owner.id]
            if names is not None and not node.func.attr.startswith(names):
                continue
            for inner in ast.walk(node):
                if isinstance(inner, ast.Constant) and isinstance(inner.value, str):
                    if inner.value == "fhnn" or inner.value.startswith("python"):
                        return True
    return False


#: Functions that import a module named at run time.
_BY_NAME = {"import_module", "spec_from_file_location", "__import__", "run_path", "run_module"}


def _imports_by_name(tree: ast.AST) -> bool:
    """Whether code calls a function that imports a module named at run time."""
    for node in ast.walk(tree):
        if isinstance(node, ast.Call):
            func = node.func
            name = func.attr if isinstance(func, ast.Attribute) else getattr(func, "id", None)
            if name in _BY_NAME:
                return True
    return False


def _imports(tree: ast.AST, package: list[str]) -> tuple[list[tuple[str, list[str]]], set[str]]:
    """The imports written anywhere in ``tree`` (a file of package ``package``, ``[]`` outside
    the package): ``(module, names)`` pairs, absolute (``names`` empty for ``import module``),
    and the names the bare package ``fhnn`` is bound to."""
    found: list[tuple[str, list[str]]] = []
    bound: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                found.append((alias.name, []))
                if alias.name.split(".")[0] == "fhnn" and (alias.asname is None or alias.name == "fhnn"):
                    bound.add(alias.asname or "fhnn")
        elif isinstance(node, ast.ImportFrom):
            name = node.module or ""
            if node.level:
                name = ".".join(package[: len(package) - node.level + 1] + ([name] if name else []))
            found.append((name, [alias.name for alias in node.names]))
    return found, bound


def _local(name: str, names: list[str], path: Path) -> list[Path]:
    """The files of module ``name`` (and of its submodules among ``names``) found beside ``path``,
    a file outside the package, or one folder up (a script's helpers, the repository's ``tests``
    package); none for a module installed elsewhere."""
    found: list[Path] = []
    for base in (path.parent, path.parent.parent):
        for parts in [name.split(".")] + [[*name.split("."), sub] for sub in names]:
            folder = base.joinpath(*parts)
            for candidate in (folder.with_suffix(".py"), folder / "__init__.py"):
                if candidate.is_file():
                    found.append(candidate)
            # the packages above it run first
            found.extend(base.joinpath(*parts[:i], "__init__.py") for i in range(1, len(parts)))
    return [f for f in found if f.is_file()]


@functools.cache
def _top_level_names(text: str) -> frozenset[str] | None:
    """The names a module's source ``text`` binds at its top level; ``None`` where it defines a
    module ``__getattr__`` (any name)."""
    names: set[str] = set()
    for node in ast.parse(text).body:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            names.add(node.name)
        elif isinstance(node, (ast.Import, ast.ImportFrom)):
            names.update((a.asname or a.name).split(".")[0] for a in node.names)
        elif isinstance(node, (ast.Assign, ast.AnnAssign, ast.AugAssign)):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            names.update(n.id for target in targets for n in ast.walk(target) if isinstance(n, ast.Name))
    return None if "__getattr__" in names else frozenset(names)


def _unbound(path: Path, name: str) -> bool:
    """Whether the module file ``path`` binds no ``name`` at its top level (and defines no module
    ``__getattr__``)."""
    defined = _top_level_names(path.read_text())
    return defined is not None and name not in defined


def _package_attributes(tree: ast.AST, bound: set[str], lazy: Mapping[str, str]) -> list[str]:
    """The names ``tree`` reads as ``fhnn.<name>`` through the names in ``bound``; every lazy
    public name where it passes the package itself on."""
    held = {id(n.value) for n in ast.walk(tree) if isinstance(n, ast.Attribute)}
    names = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id in bound:
            names.append(node.attr)
        elif isinstance(node, ast.Name) and node.id in bound and id(node) not in held:
            names.extend(lazy)
    return names


@functools.cache
def _facts(
    text: str, package: tuple[str, ...], lazy: tuple[tuple[str, str], ...]
) -> tuple[bool, bool, tuple[tuple[str, tuple[str, ...]], ...], tuple[str, ...]]:
    """What a file's source ``text`` (of package ``package``, ``()`` outside the package) says,
    read once per text: whether it starts Python processes (:func:`_starts_python`) and imports
    by name (:func:`_imports_by_name`), its imports (:func:`_imports`) and the package's
    attributes it reads (:func:`_package_attributes`, given the lazy names ``lazy``)."""
    tree = ast.parse(text)
    imports, bound = _imports(tree, list(package))
    attributes = _package_attributes(tree, bound, dict(lazy))
    return (
        _starts_python(tree),
        _imports_by_name(tree),
        tuple((name, tuple(names)) for name, names in imports),
        tuple(attributes),
    )


def _reached(
    path: Path,
    imports: tuple[tuple[str, tuple[str, ...]], ...],
    attributes: tuple[str, ...],
    root: Path,
    lazy: Mapping[str, str],
) -> list[Path]:
    """The files the imports written in ``path`` (anywhere in it: ``imports`` and the package's
    ``attributes`` it reads, from :func:`_facts`) can run: modules of the package under ``root``
    and, for a file outside it, helper scripts beside it.

    Raises:
        ValueError: an import names a module of the package that is not under ``root``.
    """
    inside = path.is_relative_to(root)
    found: list[Path] = []

    def module(name: str) -> None:
        files = _module(name, root)
        if files is None:
            raise ValueError(f"{path.name} imports {name}, which is not a module under {root}")
        found.extend(files)

    def attribute(name: str) -> None:
        """``fhnn.<name>``: a lazy public name or a subpackage."""
        if name in lazy:
            module(lazy[name])
        elif _module(f"fhnn.{name}", root) is not None:
            module(f"fhnn.{name}")

    for name, names in imports:
        if name.split(".")[0] == "fhnn":
            module(name)
            own = found[-1]  # the module's file: its package's __init__.py, or its .py
            for sub in names:
                if name == "fhnn":
                    attribute(sub)
                elif _module(f"{name}.{sub}", root) is not None:
                    module(f"{name}.{sub}")
                elif sub != "*" and own.name == "__init__.py" and _unbound(own, sub):
                    module(f"{name}.{sub}")  # neither a submodule nor a name of the package: refused
        elif not inside:
            found.extend(_local(name, names, path))
    for name in attributes:
        attribute(name)
    return found


def import_closure(script: Path, root: Path | None = None) -> list[str] | None:
    """The results-affecting files (:func:`result_files`, relative to ``root``) that running
    ``script`` can execute: those its imports reach, followed through the package's modules and
    the helper scripts beside it. The package imports no module it finds by scanning and names
    no module in a string but in its lazy table (``tests/test_results_current.py`` checks both),
    so its written imports bound what runs. Processes started with the same interpreter (a pool's
    workers) run functions of modules the script reached.

    Args:
        script: a Python file, inside or outside the package.
        root: the package's folder (default :data:`fhnn.runtime.PACKAGE_ROOT`).

    Returns:
        The sorted paths, or ``None`` when something reached starts Python processes of its own
        (``sys.executable``, the ``fhnn`` command) or, outside the package, imports a module
        named at run time: what runs then, the written imports do not bound.

    Raises:
        ValueError: an import names a module of the package that is not under ``root``.
    """
    base = (PACKAGE_ROOT if root is None else Path(root)).resolve()
    lazy = _lazy_names(base)
    table = tuple(sorted(lazy.items()))
    seen: set[Path] = set()
    queue = [Path(script).resolve()]
    while queue:
        path = queue.pop()
        if path in seen:
            continue
        seen.add(path)
        inside = path.is_relative_to(base)
        package = ("fhnn", *path.relative_to(base).parent.parts) if inside else ()
        starts, by_name, imports, attributes = _facts(path.read_text(), package, table)
        if starts or (not inside and by_name):
            return None
        queue.extend(p.resolve() for p in _reached(path, imports, attributes, base, lazy))
    affecting = set(result_files_under(base))
    return sorted(
        rel for p in seen if p.is_relative_to(base) and (rel := p.relative_to(base).as_posix()) in affecting
    )


def judged_files(stamp: Mapping[str, object], script: Path | None = None) -> tuple[object, bool]:
    """The files whose code a result stamped with ``stamp`` is judged by, and whether they are
    bounded by its script: with ``script`` and the stamp's ``file_digests``, the files of
    :func:`import_closure` it recorded (``True``); else the stamp's ``files`` as recorded, or
    every results-affecting file where it has none (``False``).

    Raises:
        ValueError: the script's imports cannot be followed (:func:`import_closure`).
    """
    digests = stamp.get("file_digests")
    closure = None if script is None or digests is None else import_closure(script)
    if closure is not None:
        # a file it did not record did not exist then: reached now through the script alone (a
        # changed file that reaches it is judged too), which no stamp covers
        return [f for f in closure if f in digests], True
    files = stamp.get("files")
    return (result_files() if files is None else files), False


def stale_reason(stamp: Mapping[str, object], script: Path | None = None) -> str | None:
    """Why a result stamped with ``stamp`` (a provenance record) was made by other code than the
    current, or ``None`` when it was not.

    Args:
        stamp: the result's provenance.
        script: the script that made it. Where given, and where the stamp records
            ``file_digests``, only the files :func:`import_closure` finds the script reaches are
            judged; otherwise every file of the stamp's ``files``.

    Raises:
        ValueError: ``stamp`` lacks ``source``, or its ``files`` is not a list of strings, or
            its ``file_digests`` not a mapping of paths to digests.
    """
    if "source" not in stamp:
        raise ValueError("the provenance has no 'source' digest")
    digests = stamp.get("file_digests")
    if digests is not None and not (
        isinstance(digests, Mapping) and all(isinstance(v, str) for v in digests.values())
    ):
        raise ValueError("the provenance's 'file_digests' is not a mapping of paths to digests")
    try:
        judged, bounded = judged_files(stamp, script)
    except ValueError as e:  # a module it imports is gone: a file that imports it changed
        return f"its script's imports cannot be followed: {e}"
    if bounded:
        now = file_digests(judged)
        changed = [f for f in judged if now[f] != digests[f]]
        if changed:
            names = ", ".join(changed[:3])
            return f"the code of {len(changed)} of the {len(judged)} files its script runs changed ({names})"
        return None
    files = stamp.get("files")
    if files is None:
        current = source_now(judged)
        if stamp["source"] != current:
            return f"its source {stamp['source']} is not the current {current}"
        return None
    if not isinstance(files, list) or not all(isinstance(f, str) for f in files):
        raise ValueError("the provenance's 'files' is not a list of paths")
    missing = [f for f in files if not (PACKAGE_ROOT / f).is_file()]
    if missing:
        return f"{len(missing)} of the files it was made with are gone ({', '.join(missing[:3])})"
    current = source_now(files)
    if stamp["source"] != current:
        return f"the code of its {len(files)} files changed (source {stamp['source']}, now {current})"
    return None


__all__ = ["file_digests", "import_closure", "judged_files", "result_files", "source_now", "stale_reason"]

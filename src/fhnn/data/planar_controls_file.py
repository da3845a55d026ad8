"""A turning body's data set under logged controls, as an HDF5 file.

The file is :func:`fhnn.data.planar.write_planar`'s with two root attributes changed: ``kind`` is
``"planar_controls"`` and ``controls`` holds the control columns' names (JSON, in slot order of
the ``forces`` channel). Its own kind keeps :func:`fhnn.data.planar.read_planar`, and with it every
reader of known forces, from taking the controls for forces.
"""

from __future__ import annotations

import dataclasses
import json
import os
from collections.abc import Sequence
from pathlib import Path

import h5py
import numpy as np

from fhnn.data.planar import SPLITS, PlanarDataset, PlanarSplit, write_planar
from fhnn.errors import DataFormatError
from fhnn.files import atomic_output, check_input_file

#: The file's root attribute ``kind`` for a data set whose forces channel holds controls.
CONTROLS_KIND = "planar_controls"
#: Each split array's shape after its leading ``(N,)`` or ``(N, T)``.
_TRAILING = {
    "t": (),
    "states": (6,),
    "states_clean": (6,),
    "forces": (3,),
    "thrust": (3, 3, 3),
    "lengths": (),
}


def write_controlled(dataset: PlanarDataset, controls: Sequence[str], path: str | os.PathLike[str]) -> Path:
    """Write ``dataset``, whose first ``len(controls)`` force slots hold the named controls, to
    an HDF5 file at ``path`` (whole or not at all); returns the path.

    Raises:
        ValueError: ``controls`` is empty or longer than 3.
        DataFormatError: ``path`` cannot be written.
    """
    if not 1 <= len(controls) <= 3:
        raise ValueError(f"a data set holds 1 to 3 controls, got {len(controls)}")
    with atomic_output(path) as tmp:
        write_planar(dataset, tmp)
        with h5py.File(tmp, "r+") as f:
            f.attrs["kind"] = CONTROLS_KIND
            f.attrs["controls"] = json.dumps(list(controls))
    return Path(path)


def file_kind(path: str | os.PathLike[str]) -> str | None:
    """The root attribute ``kind`` of the HDF5 file at ``path``; ``None`` when it has none.

    Raises:
        DataFormatError: ``path`` is missing, a folder or not an HDF5 file.
    """
    path = check_input_file(path, "an HDF5 data set")
    try:
        with h5py.File(path, "r") as f:
            kind = f.attrs.get("kind")
    except OSError as err:
        raise DataFormatError(f"{path}: not an HDF5 data set ({err})") from None
    return None if kind is None else str(kind)


def read_controlled(path: str | os.PathLike[str]) -> tuple[PlanarDataset, tuple[str, ...]]:
    """The data set and the controls' names of a file :func:`write_controlled` wrote.

    Raises:
        DataFormatError: a missing file, another kind of data set, or an array of the wrong shape.
    """
    kind = file_kind(path)
    if kind != CONTROLS_KIND:
        said = "known forces, not controls" if kind == "planar" else f"kind {kind!r}"
        raise DataFormatError(f"{path} is not a data set under controls ({said})")
    try:
        with h5py.File(path, "r") as f:
            controls = tuple(json.loads(f.attrs["controls"]))
            splits = {
                name: PlanarSplit(*(np.asarray(f[name][k.name]) for k in dataclasses.fields(PlanarSplit)))
                for name in SPLITS
            }
            meta = [f.attrs[k] for k in ("scenario", "params", "seed", "obs_noise", "mass", "inertia", "x_g")]
    except (OSError, KeyError, ValueError) as err:
        raise DataFormatError(f"{path}: not a readable data set under controls ({err})") from None
    for name, split in splits.items():
        lead = split.states.shape[:2]
        for key, trailing in _TRAILING.items():
            want = (lead[0], *trailing) if key in ("thrust", "lengths") else (*lead, *trailing)
            shape = getattr(split, key).shape
            if shape != want:
                raise DataFormatError(f"{path}: {name}/{key} has shape {shape}, not {want}")
    if not 1 <= len(controls) <= 3 or not all(isinstance(c, str) for c in controls):
        raise DataFormatError(f"{path}: its 'controls' attribute is not 1 to 3 names")
    scenario, params, seed, noise, mass, inertia, x_g = meta
    dataset = PlanarDataset(
        str(scenario),
        json.loads(params),
        int(seed),
        float(noise),
        float(mass),
        float(inertia),
        float(x_g),
        splits,
    )
    return dataset, controls


__all__ = ["CONTROLS_KIND", "file_kind", "read_controlled", "write_controlled"]

"""``fhnn info`` as one function for either body: a point body's data set or a turning body's.

::

    import fhnn

    fhnn.info("data/steady.h5")     # a point body's: scenario, parameters, splits, covered r, speed, σ
    fhnn.info("data/turning.h5")    # a turning body's: the body, splits, covered states
"""

from __future__ import annotations

import os
from typing import Any

from fhnn.api.data import info as point_info
from fhnn.api.planar_info import is_turning_data, turning_info
from fhnn.data.dataset import Dataset
from fhnn.data.planar import PlanarDataset


def is_turning(data: Dataset | PlanarDataset | str | os.PathLike[str]) -> bool:
    """Whether ``data`` is a turning body's data set or its HDF5 file (known forces or controls)."""
    return isinstance(data, PlanarDataset) or (not isinstance(data, Dataset) and is_turning_data(data))


def info(data: Dataset | PlanarDataset | str | os.PathLike[str]) -> dict[str, Any]:
    """What ``fhnn info`` prints of a data set, whichever body it holds.

    Args:
        data: a data set, or the HDF5 file ``fhnn simulate``, ``fhnn import`` or ``fhnn turning
            simulate`` wrote.

    Returns:
        For a point body's, :func:`fhnn.api.data.info`'s summary (scenario, parameters, split
        sizes, the ranges of ``r`` [m], speed [m/s] and σ covered); for a turning body's,
        :func:`fhnn.api.planar_info.turning_info`'s (the body, split sizes, the ranges of ``x, y``
        [m], heading [rad], ``u, v`` [m/s] and ``r`` [rad/s] covered).

    Raises:
        DataFormatError: ``data`` is missing, unreadable or not an fhnn data set.
    """
    return turning_info(data) if is_turning(data) else point_info(data)


__all__ = ["info", "is_turning"]

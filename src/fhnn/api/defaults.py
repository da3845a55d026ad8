"""Defaults of the public functions that the command line's help texts show, in a module that
imports nothing, so that ``fhnn --help`` and every command start without loading the functions'
own dependencies."""

from __future__ import annotations

#: The seconds of each track's end the start state is fitted to, by default
#: (:func:`fhnn.api.planar_forecast.forecast_turning`): on the shipmmg check's held-out manoeuvres
#: (2 cm, 0.2° noise at ~0.5 s), fitting the first 10 s cut a perfect model's 60 s forecast error
#: 5- to 25-fold against the smoothed start (docs/design/turning.md).
FIT_WINDOW = 10.0

__all__ = ["FIT_WINDOW"]

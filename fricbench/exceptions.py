"""Errors shared by every fitted object of fricbench (predictors, compensators, the diagnosis)."""

from __future__ import annotations

__all__ = ["NotFittedError"]


class NotFittedError(RuntimeError):
    """A learned object used before ``fit`` (``predict``, ``act``, ``reset``, ``save``).

    One class for the whole package, so that ``except NotFittedError`` catches it whatever
    raised it (as scikit-learn's ``sklearn.exceptions.NotFittedError``).
    """

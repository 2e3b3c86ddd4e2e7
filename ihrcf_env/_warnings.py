"""The package's own warning filters, in one place."""

from __future__ import annotations

import warnings
from collections.abc import Iterator
from contextlib import contextmanager

__all__ = ["OUT_OF_DATE", "older_version_allowed"]

#: Gymnasium's message for an id with a newer version registered (``DeckLanding-v1`` beside v2).
OUT_OF_DATE = ".*is out of date"


@contextmanager
def older_version_allowed() -> Iterator[None]:
    """Silences Gymnasium's warning that a newer version of an id exists, for code that makes an
    older id (``ihrcf_env/DeckLanding-v1``) on purpose; other warnings pass."""
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=OUT_OF_DATE, category=DeprecationWarning)
        yield

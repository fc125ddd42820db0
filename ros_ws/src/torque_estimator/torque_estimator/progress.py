"""A progress bar for long work (tqdm on a terminal, silent when disabled)."""
from __future__ import annotations

import sys

from tqdm import tqdm


class ProgressBar:
    """Context manager around tqdm with an absolute `update_to`."""

    def __init__(self, total: int, unit: str, enabled: bool = True) -> None:
        self._bar = tqdm(total=total, desc=unit, disable=not enabled, file=sys.stderr, leave=False)

    def update_to(self, done: int) -> None:
        self._bar.update(max(0, done - self._bar.n))

    def __enter__(self) -> "ProgressBar":
        return self

    def __exit__(self, *exc) -> None:
        self._bar.close()

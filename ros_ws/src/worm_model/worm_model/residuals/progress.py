"""A minimal progress bar for the residuals CLI (tqdm on stderr; silent when disabled).

worm_model cannot import torque_estimator's ProgressBar (torque_estimator depends on
worm_model), so this is the same small wrapper.
"""
from __future__ import annotations

import sys

from tqdm import tqdm


class Progress:
    """One bar per stage: ``stage(name, total)`` then ``update_to(done)``."""

    def __init__(self, enabled: bool = True) -> None:
        self.enabled = enabled
        self._bar: tqdm | None = None
        self._name = ""

    def stage(self, name: str, total: int) -> None:
        self.close()
        self._name = name
        self._bar = tqdm(total=total, desc=name, disable=not self.enabled, file=sys.stderr, leave=False)

    @property
    def name(self) -> str:
        """The current stage's label."""
        return self._name

    def update_to(self, done: int) -> None:
        if self._bar is not None:
            self._bar.update(max(0, done - self._bar.n))

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()
            self._bar = None

    def __enter__(self) -> "Progress":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

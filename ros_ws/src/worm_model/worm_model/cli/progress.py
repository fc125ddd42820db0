"""Progress bars for long work in every command-line tool (tqdm on stderr, silent when disabled, and when
stderr is not a terminal: in a log or a pipe a bar is noise, and a refusal must stay one line)."""
from __future__ import annotations

import sys

from tqdm import tqdm


class ProgressBar:
    """One bar: context manager around tqdm with an absolute ``update_to``."""

    def __init__(self, total: int, unit: str, enabled: bool = True) -> None:
        self._bar = tqdm(total=total, desc=unit, disable=not enabled or not sys.stderr.isatty(), file=sys.stderr,
                         leave=False)

    def update_to(self, done: int) -> None:
        self._bar.update(max(0, done - self._bar.n))

    def close(self) -> None:
        self._bar.close()

    def __enter__(self) -> "ProgressBar":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class Progress:
    """One bar per stage of a multi-stage job: ``stage(name, total)`` then ``update_to(done)``."""

    def __init__(self, enabled: bool = True) -> None:
        self.enabled = enabled
        self._bar: ProgressBar | None = None
        self._name = ""

    def stage(self, name: str, total: int) -> None:
        self.close()
        self._name = name
        self._bar = ProgressBar(total, name, self.enabled)

    @property
    def name(self) -> str:
        """The current stage's label."""
        return self._name

    def update_to(self, done: int) -> None:
        if self._bar is not None:
            self._bar.update_to(done)

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()
            self._bar = None

    def __enter__(self) -> "Progress":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

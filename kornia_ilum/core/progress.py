"""A progress bar on stderr for long commands: tqdm when it is installed, else a plain counter."""

from __future__ import annotations

import sys
from collections.abc import Iterable, Iterator
from typing import TypeVar

__all__ = ["ProgressBar", "progress"]

T = TypeVar("T")


class ProgressBar:
    """A progress bar on stderr: tqdm when installed, else a ``desc: i/total`` counter (every 1 %).

    When stderr is not a terminal (a log file, a pipe, CI), neither: a plain line ``desc: i/total`` every 10 %,
    so that a log holds a few readable lines instead of hundreds of carriage-return updates run together.

    Args:
        total: the number of steps.
        desc: the label before the count.
        unit: what one step is (tqdm's ``unit``).

    Examples:
        >>> bar = ProgressBar(2, "renders", "light")
        >>> bar.update(2)
        >>> bar.close()
    """

    def __init__(self, total: int, desc: str, unit: str) -> None:
        self.total, self.desc, self.done, self.shown = total, desc, 0, -1
        self.lines = not _is_terminal(sys.stderr)  # a log: plain lines, not carriage returns
        self.tqdm = None
        if not self.lines:
            try:
                from tqdm import tqdm  # optional dependency: a plain counter without it
            except ImportError:
                pass
            else:
                self.tqdm = tqdm(total=total, desc=desc, file=sys.stderr, unit=unit)

    def update(self, n: int = 1) -> None:
        self.done += n
        if self.tqdm is not None:
            self.tqdm.update(n)
        elif self.lines:
            step = 10 * self.done // max(self.total, 1)
            if self.done == self.total or step > self.shown:
                self.shown = step
                print(f"{self.desc}: {self.done}/{self.total}", file=sys.stderr, flush=True)
        elif self.done == self.total or 100 * self.done // max(self.total, 1) > self.shown:
            self.shown = 100 * self.done // max(self.total, 1)
            end = "\n" if self.done == self.total else ""
            print(f"\r{self.desc}: {self.done}/{self.total}", end=end, file=sys.stderr, flush=True)

    def close(self) -> None:
        if self.tqdm is not None:
            self.tqdm.close()


def _is_terminal(stream: object) -> bool:
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError):  # no isatty, or a closed stream
        return False


def progress(items: Iterable[T], total: int, desc: str, unit: str = "item") -> Iterator[T]:
    """Iterate ``items`` with a :class:`ProgressBar` of ``total`` steps.

    Args:
        items: what to iterate.
        total: the number of steps shown (``len(items)`` for a sequence).
        desc: the label before the count.
        unit: what one step is (tqdm's ``unit``).

    Returns:
        an iterator over ``items``; the bar advances after each item and closes when the loop ends or stops.

    Examples:
        >>> list(progress(["a", "b"], 2, "files", "file"))  # the bar goes to stderr
        ['a', 'b']
    """
    bar = ProgressBar(total, desc, unit)
    try:
        for item in items:
            yield item
            bar.update()
    finally:  # also when the loop stops early
        bar.close()

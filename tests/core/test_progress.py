"""Tests of kornia_ilum.core.progress: the progress bar on stderr (tqdm when installed, else a counter)."""

from __future__ import annotations

import sys

import pytest

from kornia_ilum.core.progress import ProgressBar, progress


@pytest.fixture
def no_tqdm(monkeypatch):
    """The plain counter: ``import tqdm`` fails."""
    monkeypatch.setitem(sys.modules, "tqdm", None)


def test_counter_ends_with_the_total(no_tqdm, capsys):
    bar = ProgressBar(3, "renders", "light")
    for _ in range(3):
        bar.update()
    bar.close()
    err = capsys.readouterr().err
    assert err.endswith("renders: 3/3\n")
    assert capsys.readouterr().out == ""


def test_progress_yields_every_item_in_order(no_tqdm, capsys):
    assert list(progress(iter("abc"), 3, "items")) == ["a", "b", "c"]
    assert capsys.readouterr().err.endswith("items: 3/3\n")


def test_progress_closes_when_the_loop_stops_early(no_tqdm, monkeypatch):
    closed = []
    monkeypatch.setattr(ProgressBar, "close", lambda self: closed.append(self.done))
    items = progress(range(10), 10, "items")
    for item in items:
        if item == 2:
            break
    items.close()
    assert closed == [2]  # closed once, after the two items that finished


def test_a_log_gets_a_few_plain_lines(capsys):
    """Issue 25: piped into a file, 104 updates make at most 11 lines and no carriage return."""
    bar = ProgressBar(104, "OLAT renders", "light")  # capsys' stderr is no terminal
    for _ in range(104):
        bar.update()
    bar.close()
    err = capsys.readouterr().err
    assert "\r" not in err and err.endswith("OLAT renders: 104/104\n")
    assert 2 <= len(err.splitlines()) <= 11


def test_a_terminal_gets_the_counter(no_tqdm, capsys, monkeypatch):
    monkeypatch.setattr(sys.stderr, "isatty", lambda: True, raising=False)
    bar = ProgressBar(3, "renders", "light")
    bar.update(3)
    assert "\r" in capsys.readouterr().err

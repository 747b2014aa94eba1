"""Tests of cagekit.progress: a bar on stderr only when wanted, a no-op otherwise."""

import sys

from cagekit.progress import bar_callback, progress_bar, progress_enabled


def test_a_disabled_bar_is_a_no_op(capsys):
    bar = progress_bar("work", "item", total=3, enabled=False)
    bar.update(2)
    bar.close()
    with progress_bar("work", "item", total=3, enabled=False) as bar:
        bar.update(3)
    assert capsys.readouterr() == ("", "")


def test_by_default_no_bar_when_stderr_is_not_a_terminal(capsys):
    with progress_bar("work", "item", total=3) as bar:
        bar.update(3)
    assert capsys.readouterr() == ("", "")


def test_an_enabled_bar_writes_to_stderr_only(capsys):
    with progress_bar("work", "item", total=5, enabled=True) as bar:
        for _ in range(5):
            bar.update(1)
    out, err = capsys.readouterr()
    assert out == "" and "work" in err and "0/5" in err
    # leave=False: the finished bar is cleared from its line
    assert err.rsplit("\r", 1)[-1].strip() == ""


def test_leave_keeps_the_final_count(capsys):
    with progress_bar("sample", "shape", total=4, enabled=True, leave=True) as bar:
        bar.update(4)
    out, err = capsys.readouterr()
    assert out == "" and err.endswith("\n")
    last = err.rstrip("\n").rsplit("\r", 1)[-1]
    assert "sample" in last and "4/4" in last and "100%" in last


def test_initial_starts_a_resumed_bar(capsys):
    with progress_bar("train", "step", total=10, initial=4, enabled=True, leave=True) as bar:
        assert bar.n == 4
        bar.update(6)
    assert "10/10" in capsys.readouterr().err


def test_bar_callback_sets_count_and_total(capsys):
    bar = progress_bar("bind", "point", enabled=False)
    progress = bar_callback(bar)
    progress(3, 10)
    assert bar.n == 3 and bar.total == 10
    progress(12, 10)  # never past the total
    assert bar.n == 10 and bar.total == 10
    bar.close()
    with progress_bar("bind", "point", enabled=True, leave=True) as shown:
        bar_callback(shown)(7, 8)
    assert "7/8" in capsys.readouterr().err


def test_progress_enabled_only_on_a_terminal(monkeypatch, capsys):
    assert progress_enabled() is False  # capsys: stderr is not a terminal

    class Terminal:
        def isatty(self):
            return True

    class Closed:
        def isatty(self):
            raise ValueError("I/O operation on closed file")

    monkeypatch.setattr(sys, "stderr", Terminal())
    assert progress_enabled() is True
    monkeypatch.setattr(sys, "stderr", Closed())
    assert progress_enabled() is False
    monkeypatch.setattr(sys, "stderr", object())  # no isatty at all
    assert progress_enabled() is False

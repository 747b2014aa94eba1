"""Tests of cagekit.io.files: atomic output, output folders, temporaries left by killed writers."""

import os

import pytest
from builders import write

from cagekit.errors import InputError
from cagekit.io import files as cfiles


def test_atomic_output_replaces_on_success_only(tmp_path):
    target = write(tmp_path / "result.json", "old")
    os.chmod(target, 0o640)
    with pytest.raises(RuntimeError), cfiles.atomic_output(target) as tmp:
        assert os.path.dirname(tmp) == str(tmp_path) and tmp.endswith(".json")
        write(tmp, "half written")
        raise RuntimeError("crash while writing")
    assert target.read_text() == "old" and os.listdir(tmp_path) == ["result.json"]
    with cfiles.atomic_output(target) as tmp:
        write(tmp, "new")
        assert target.read_text() == "old"
    assert target.read_text() == "new" and os.listdir(tmp_path) == ["result.json"]
    assert os.stat(target).st_mode & 0o777 == 0o640
    with cfiles.atomic_output(tmp_path / "fresh.png") as tmp:
        write(tmp, b"\x89PNG")
    assert (tmp_path / "fresh.png").read_bytes() == b"\x89PNG"


def _save_in_a_new_process(target, timeout=60):
    """``save_mesh(target)`` in another process: the "next run" of a command."""
    import subprocess
    import sys

    code = ("import sys\nfrom cagekit.io import save_mesh\n"
            "save_mesh(sys.argv[1], [[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]])\n")
    subprocess.run([sys.executable, "-c", code, str(target)], check=True, timeout=timeout)


def test_a_killed_writers_temporary_is_removed_by_the_next_run(tmp_path):
    """SIGKILL leaves a hidden temporary behind; the next run writing into the folder
    removes it, while a live writer's temporary (locked) is left alone."""
    import signal
    import subprocess
    import sys

    target = tmp_path / "big.obj"
    code = ("import sys, time\n"
            "from cagekit.io.files import atomic_output\n"
            "with atomic_output(sys.argv[1]) as tmp:\n"
            "    open(tmp, 'w').write('x' * 100000)\n"
            "    print('writing', flush=True)\n"
            "    time.sleep(600)\n")
    writer = subprocess.Popen([sys.executable, "-c", code, str(target)],
                              stdout=subprocess.PIPE, text=True)
    try:
        assert writer.stdout.readline().strip() == "writing"
        (temporary,) = [n for n in os.listdir(tmp_path) if n.startswith(".big.tmp-")]
        _save_in_a_new_process(target)  # the writer is alive: its file stays
        assert temporary in os.listdir(tmp_path)
    finally:
        writer.send_signal(signal.SIGKILL)
        writer.wait()
    assert temporary in os.listdir(tmp_path)  # what SIGKILL leaves
    (tmp_path / "notes.txt").write_text("not a temporary")
    _save_in_a_new_process(target)
    assert sorted(os.listdir(tmp_path)) == ["big.obj", "notes.txt"]


def test_a_fifo_named_like_a_temporary_does_not_block_writes(tmp_path):
    os.mkfifo(tmp_path / ".a.tmp-0123abcd.obj")
    _save_in_a_new_process(tmp_path / "a.obj", timeout=30)  # no hang
    assert sorted(os.listdir(tmp_path)) == [".a.tmp-0123abcd.obj", "a.obj"]


def test_output_folder_removes_the_folders_it_made_when_the_block_fails(tmp_path):
    with pytest.raises(RuntimeError), cfiles.output_folder(tmp_path / "a" / "b" / "c"):
        raise RuntimeError("the run failed")
    assert os.listdir(tmp_path) == []
    (tmp_path / "kept").mkdir()
    with pytest.raises(KeyboardInterrupt), cfiles.output_folder(tmp_path / "kept" / "new"):
        raise KeyboardInterrupt
    assert os.listdir(tmp_path) == ["kept"] and os.listdir(tmp_path / "kept") == []
    with cfiles.output_folder(tmp_path / "x" / "y") as folder:
        write(os.path.join(folder, "f.txt"), "out")
    assert (tmp_path / "x" / "y" / "f.txt").read_text() == "out"
    write(tmp_path / "file", "a file")
    with pytest.raises(InputError, match="is not a folder"), \
            cfiles.output_folder(tmp_path / "file" / "sub"):
        pass


def _written(path, text):
    with cfiles.atomic_output(path) as tmp, open(tmp, "w") as handle:
        handle.write(text)


def test_all_or_nothing_removes_what_a_failed_block_made(tmp_path):
    old = tmp_path / "old.txt"
    old.write_text("before")
    with pytest.raises(KeyboardInterrupt):
        with cfiles.all_or_nothing():
            _written(old, "after")  # replaced: keeps its new content
            _written(tmp_path / "new.txt", "new")
            with cfiles.output_folder(tmp_path / "made" / "deeper") as folder:
                _written(os.path.join(folder, "inside.txt"), "x")
                _written(os.path.join(folder, "inside.txt"), "y")  # written twice
            raise KeyboardInterrupt
    assert sorted(os.listdir(tmp_path)) == ["old.txt"]  # no new file, no folder left
    assert old.read_text() == "after"
    # a dangling link at an output path was there before: it is replaced, never removed
    (tmp_path / "link.txt").symlink_to(tmp_path / "nowhere")
    with pytest.raises(RuntimeError):
        with cfiles.all_or_nothing():
            _written(tmp_path / "link.txt", "through the link")
            raise RuntimeError
    assert os.path.lexists(tmp_path / "link.txt")


def test_all_or_nothing_keeps_the_outputs_of_a_block_that_completes_or_exits(tmp_path):
    with cfiles.all_or_nothing():
        _written(tmp_path / "new.txt", "new")
    assert (tmp_path / "new.txt").read_text() == "new"
    with pytest.raises(SystemExit):  # click exits so when a reader closes its pipe
        with cfiles.all_or_nothing():
            _written(tmp_path / "exited.txt", "done")
            raise SystemExit(1)
    assert (tmp_path / "exited.txt").exists()
    # a resumable batch keeps what it wrote so far and from then on
    with pytest.raises(RuntimeError):
        with cfiles.all_or_nothing():
            _written(tmp_path / "first.txt", "1")
            cfiles.keep_outputs_as_written()
            _written(tmp_path / "second.txt", "2")
            raise RuntimeError
    assert (tmp_path / "first.txt").exists() and (tmp_path / "second.txt").exists()
    assert cfiles._JOURNAL is None  # outside a block nothing is recorded
    # a block inside another hands what it made to the outer one
    with pytest.raises(RuntimeError):
        with cfiles.all_or_nothing():
            with cfiles.all_or_nothing():
                _written(tmp_path / "inner.txt", "i")
            raise RuntimeError
    assert not (tmp_path / "inner.txt").exists()


def test_missing_folders_are_those_the_system_would_make(tmp_path):
    from cagekit.io.files import missing_folders

    (tmp_path / "d" / "sub").mkdir(parents=True)
    os.symlink(tmp_path / "d" / "sub", tmp_path / "link")
    assert missing_folders(tmp_path / "d") == []
    assert missing_folders(tmp_path / "a" / "b") == [str(tmp_path / "a" / "b"),
                                                     str(tmp_path / "a")]
    # "link/../out" is d/out to the system, not tmp_path/out as the text reads
    assert missing_folders(tmp_path / "link" / ".." / "out") == [
        os.path.realpath(tmp_path / "d" / "out")]
    with cfiles.output_folder(tmp_path / "link" / ".." / "out"):
        pass
    assert (tmp_path / "d" / "out").is_dir() and not (tmp_path / "out").exists()

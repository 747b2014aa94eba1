"""Robustness of ``cagekit amplify`` (issue 29): each source's own cage, worker processes
that die with the batch, an output folder kept out of its collection, and a capped
``--workers``."""

import json
import multiprocessing.util
import os
import queue
import shutil
import signal
import subprocess
import sys
import threading
import time
import warnings
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import psutil
import pytest
from builders import ROOT, assert_bad_input, cagekit, invoke

import cagekit.batch.amplify as batch
from cagekit.batch.amplify import amplify
from cagekit.batch.collection import find_shapes
from cagekit.datasets import synthetic
from cagekit.errors import CagekitWarning
from cagekit.io import load_mesh, save_mesh

#: a filter that keeps every variation in variations/
KEEP_ALL = {"max_cd": 1e9, "max_nonaffinity": 1e9}


def manifest_of(out):
    return json.loads((out / "manifest.json").read_text())


def variations_of(out):
    return {name: load_mesh(out / "variations" / name)[0]
            for name in sorted(os.listdir(out / "variations")) if not name.startswith(".")}


def one_line_messages(stderr):
    """The lines of stderr, each checked to be one of the command's own one-line messages
    (a worker's output, a traceback or a multi-line warning is not)."""
    lines = stderr.strip().splitlines()
    assert all(line.startswith("cagekit amplify: ") for line in lines), stderr
    return lines


# ------------------------------------------------------------------- one cage per source


@pytest.fixture(scope="module")
def flattening(tmp_path_factory):
    """``a/chair`` and ``a-chair`` (whose names flatten to one file name), and a finished
    batch of their two pairs, fitted with the cage method."""
    root = tmp_path_factory.mktemp("flattening")
    collection = root / "shapes"
    (collection / "a").mkdir(parents=True)
    save_mesh(collection / "a" / "chair.obj", *synthetic.vase(seed=0, resolution=0.5))
    save_mesh(collection / "a-chair.obj", *synthetic.vase(seed=1, resolution=0.5))
    out = root / "out"
    rows = amplify(str(collection), str(out), pairs="all", workers=1, **KEEP_ALL)
    return collection, out, rows


def resumed(flattening, tmp_path):
    """A copy of the fixture's collection and finished batch to change and resume."""
    collection, out, _ = flattening
    shutil.copytree(collection, tmp_path / "shapes")
    shutil.copytree(out, tmp_path / "out")
    return tmp_path / "shapes", tmp_path / "out"


def test_sources_whose_names_flatten_alike_get_a_cage_each(flattening, tmp_path):
    _, out, first = flattening
    assert all(r["status"] == "ok" and r["cage_seconds"] > 0 for r in first)
    files = {name: entry["file"] for name, entry in manifest_of(out)["cages"].items()}
    assert sorted(files) == ["a-chair", "a/chair"]
    assert len(set(files.values())) == 2, files
    assert sorted(os.listdir(out / "cages")) == sorted(files.values())
    # a resumed batch reuses each source's own cage: it makes the same variations
    collection, again = resumed(flattening, tmp_path)
    before = variations_of(again)
    for name in before:
        os.remove(again / "variations" / name)
    rows = amplify(str(collection), str(again), pairs="all", workers=1, **KEEP_ALL)
    assert [r["cage_seconds"] for r in rows] == [0, 0]  # reused, not refitted
    after = variations_of(again)
    assert sorted(after) == sorted(before)
    for name in before:
        np.testing.assert_array_equal(after[name], before[name], err_msg=name)


def test_a_cage_that_is_not_its_sources_is_fitted_again(flattening, tmp_path):
    collection, out = resumed(flattening, tmp_path)
    files = {name: entry["file"] for name, entry in manifest_of(out)["cages"].items()}
    own = (out / "cages" / files["a/chair"]).read_bytes()
    before = variations_of(out)
    output = next(r["output"] for r in flattening[2] if r["source"] == "a/chair")
    # a/chair's cage file overwritten with a-chair's (as two sources sharing a file did)
    shutil.copyfile(out / "cages" / files["a-chair"], out / "cages" / files["a/chair"])
    os.remove(out / "variations" / output)
    rows = {r["source"]: r for r in amplify(str(collection), str(out), pairs="all",
                                            workers=1, **KEEP_ALL)}
    assert rows["a/chair"]["cage_seconds"] > 0  # refitted, not reused
    assert (out / "cages" / files["a/chair"]).read_bytes() == own
    np.testing.assert_array_equal(variations_of(out)[output], before[output])


def test_a_changed_source_gets_a_new_cage_recorded_with_its_hash(flattening, tmp_path):
    collection, out = resumed(flattening, tmp_path)
    entry = manifest_of(out)["cages"]["a-chair"]
    old = (out / "cages" / entry["file"]).read_bytes()
    save_mesh(collection / "a-chair.obj", *synthetic.vase(seed=2, resolution=0.5))
    rows = {r["source"]: r for r in amplify(str(collection), str(out), pairs="all",
                                            workers=1, **KEEP_ALL)}
    assert rows["a-chair"]["cage_seconds"] > 0
    shapes = {s.name: s for s in find_shapes(str(collection))}
    entry = manifest_of(out)["cages"]["a-chair"]
    assert entry["hash"] == shapes["a-chair"].fingerprint
    assert (out / "cages" / entry["file"]).read_bytes() != old


# ------------------------------------------------------ workers that die with the batch

#: how long a test waits for a batch to reach a state (it never takes this long)
PATIENCE = 240


def start_batch(out, stderr=subprocess.PIPE):
    """``cagekit amplify`` on a pool of two workers, in a session of its own (so that a
    Ctrl-C can be sent to its process group as a terminal sends it)."""
    args = [sys.executable, "-m", "cagekit.cli", "amplify", "synthetic:vases:3", "-o",
            str(out), "--variations", "6", "--workers", "2"]
    env = dict(os.environ, PYTHONPATH=ROOT + os.pathsep + os.environ.get("PYTHONPATH", ""))
    env.pop("CAGEKIT_DEBUG", None)
    return subprocess.Popen(args, env=env, stdout=subprocess.DEVNULL, stderr=stderr,
                            text=True, start_new_session=True)


def descendants(process):
    """Every process below ``process`` (pool workers, multiprocessing's resource tracker)."""
    try:
        return psutil.Process(process.pid).children(recursive=True)
    except psutil.NoSuchProcess:
        return []


def is_worker(proc):
    try:
        return "spawn_main" in " ".join(proc.cmdline())
    except psutil.Error:
        return False


def working(process, out):
    """The descendants of a batch once both its workers run and an item is recorded."""
    manifest = out / "manifest.json"
    deadline = time.monotonic() + PATIENCE
    while time.monotonic() < deadline and process.poll() is None:
        found = descendants(process)
        if sum(map(is_worker, found)) >= 2 and manifest.exists() \
                and json.loads(manifest.read_text())["items"]:
            return found
        time.sleep(0.05)
    pytest.fail(f"the batch never ran two workers (exit status {process.poll()})")


def alive(procs):
    """Those of ``procs`` still running (zombies, ended but not reaped, are not)."""
    left = []
    for proc in procs:
        try:
            if proc.is_running() and proc.status() != psutil.STATUS_ZOMBIE:
                left.append(proc)
        except psutil.NoSuchProcess:
            pass
    return left


def survivors(procs):
    """Those of ``procs`` still running after a while (killed, so none is left behind)."""
    deadline = time.monotonic() + 30
    while alive(procs) and time.monotonic() < deadline:
        time.sleep(0.1)
    left = alive(procs)
    for proc in left:
        proc.kill()
    return left


#: a pool of two workers needs two cores (fewer, and the batch runs in its own process)
two_cores = pytest.mark.skipif(batch.usable_cores() < 2, reason="a pool needs two cores")


@two_cores
def test_the_workers_end_when_the_batch_is_killed(tmp_path):
    process = start_batch(tmp_path / "out", stderr=subprocess.DEVNULL)
    procs = []
    try:
        procs = working(process, tmp_path / "out")
        process.kill()
        process.wait(timeout=60)
    finally:
        procs = procs or descendants(process)
        if process.poll() is None:
            process.kill()
        left = survivors(procs)  # killed: none is left behind, whatever failed
    assert left == []


def lines_of(stream):
    """A queue of the lines of ``stream`` as a thread reads them; None at its end."""
    lines = queue.Queue()

    def pump():
        with stream:
            for line in stream:
                lines.put(line)
        lines.put(None)

    threading.Thread(target=pump, daemon=True).start()
    return lines


def text_until(lines, end=None):
    """The lines of a :func:`lines_of` queue up to the first that holds ``end`` (or to
    the stream's end)."""
    text = ""
    while (line := lines.get(timeout=PATIENCE)) is not None:
        text += line
        if end is not None and end in line:
            break
    return text


def _ctrl_c(process):
    os.killpg(process.pid, signal.SIGINT)  # as a terminal sends Ctrl-C: to the group


def _kill(process):
    process.send_signal(signal.SIGTERM)  # as `kill PID` sends it: to the batch only


def _timeout(process):
    os.killpg(process.pid, signal.SIGTERM)  # as `timeout` sends it: to the group, workers too


@two_cores
@pytest.mark.parametrize("send, status, line", [(_ctrl_c, 130, "interrupted"),
                                                (_kill, 143, "terminated"),
                                                (_timeout, 143, "terminated")])
def test_ctrl_c_ends_the_batch_with_one_line_and_no_process_left(tmp_path, send, status,
                                                                 line):
    process = start_batch(tmp_path / "out", stderr=subprocess.PIPE)
    lines, procs = lines_of(process.stderr), []
    try:
        procs = working(process, tmp_path / "out")
        workers = [proc for proc in procs if is_worker(proc)]
        send(process)
        stderr = text_until(lines, line)
        running = alive(workers)  # as the command says it stopped: none still working
        process.wait(timeout=PATIENCE)
    finally:
        procs = procs or descendants(process)
        if process.poll() is None:
            process.kill()
        left = survivors(procs)  # killed: none is left behind, whatever failed
    stderr += text_until(lines)
    assert running == [] and left == []
    assert process.returncode == status, stderr
    errors = [m for m in one_line_messages(stderr) if ": error: " in m]
    assert errors == [f"cagekit amplify: error: {line}"] == one_line_messages(stderr)[-1:]
    items = manifest_of(tmp_path / "out")["items"]
    assert len(items) < 6  # it stopped, not ran to the end
    # the workers the signal killed with it are not its items' failures
    assert [row["status"] for row in items if row["status"] == "failed"] == []


#: runs ``cagekit amplify`` with a Ctrl-C that lands inside ``concurrent.futures.wait``
#: while it holds the first of its futures' locks (the race CI once met by chance)
CTRL_C_IN_WAIT = """
import concurrent.futures._base as base, os, runpy, signal, sys

def enter(self):
    for k, future in enumerate(self.futures):
        future._condition.acquire()
        if k == 0 and not sent:
            sent.append(True)
            os.kill(os.getpid(), signal.SIGINT)  # raised here, with a future's lock held
            for _ in range(1000):  # the bytecodes where Python runs the signal's handler
                pass

sent = []
base._AcquireFutures.__enter__ = enter
if __name__ == "__main__":
    sys.argv = ["cagekit", *sys.argv[1:]]
    runpy.run_module("cagekit.cli", run_name="__main__")
"""


@two_cores
def test_a_ctrl_c_while_the_pool_s_futures_are_locked_ends_the_batch(tmp_path):
    script = tmp_path / "ctrl_c_in_wait.py"
    script.write_text(CTRL_C_IN_WAIT)
    args = [sys.executable, str(script), "amplify", "synthetic:vases:3", "-o",
            str(tmp_path / "out"), "--variations", "6", "--workers", "2"]
    env = dict(os.environ, PYTHONPATH=ROOT + os.pathsep + os.environ.get("PYTHONPATH", ""))
    env.pop("CAGEKIT_DEBUG", None)
    process = subprocess.Popen(args, env=env, stdout=subprocess.DEVNULL,
                               stderr=subprocess.PIPE, text=True, start_new_session=True)
    procs = []
    try:
        _, stderr = process.communicate(timeout=PATIENCE)  # before: never ended
    finally:
        procs = descendants(process)
        if process.poll() is None:
            process.kill()
            stderr = "(still running)"
        left = survivors(procs)
    assert left == []
    assert process.returncode == 130, stderr
    assert one_line_messages(stderr)[-1:] == ["cagekit amplify: error: interrupted"]
    # stopped before any item finished: the folder is gone, or kept for the cages fitted
    out = tmp_path / "out"
    if out.exists():
        assert manifest_of(out)["items"] == [] and os.listdir(out / "cages")
        assert not os.listdir(out / "variations")


# ------------------------------------------------------ the output folder and collection


@pytest.fixture
def two(tmp_path):
    """A collection folder of two small vases."""
    collection = tmp_path / "shapes"
    collection.mkdir()
    for i in range(2):
        save_mesh(collection / f"v{i}.obj", *synthetic.vase(seed=i, resolution=0.5))
    return collection


@pytest.mark.parametrize("where", ["shapes", "shapes/out", "shapes/../shapes/sub/out"])
def test_an_output_folder_in_the_collection_is_refused(two, where):
    out = two.parent / where
    result = cagekit("amplify", two, "-o", out, "--variations", "1", "--method", "scale",
                     "--workers", "1")
    assert_bad_input(result, out)
    assert "collection" in result.stderr
    assert sorted(os.listdir(two)) == ["v0.obj", "v1.obj"]  # nothing written there


def test_a_collection_in_the_output_folders_is_refused(tmp_path):
    out = tmp_path / "out"
    collection = out / "variations"
    collection.mkdir(parents=True)
    for i in range(2):
        save_mesh(collection / f"v{i}.obj", *synthetic.vase(seed=i, resolution=0.5))
    result = cagekit("amplify", collection, "-o", out, "--pairs", "all", "--method", "scale",
                     "--workers", "1")
    assert_bad_input(result, out)
    assert sorted(os.listdir(out)) == ["variations"]
    assert sorted(os.listdir(collection)) == ["v0.obj", "v1.obj"]


def test_the_scan_leaves_out_the_output_folder(two):
    (two / "out" / "variations").mkdir(parents=True)
    save_mesh(two / "out" / "variations" / "v0__v1.obj", *synthetic.vase(seed=3,
                                                                          resolution=0.5))
    assert len(find_shapes(str(two))) == 3
    names = [s.name for s in find_shapes(str(two), exclude=[str(two / "out")])]
    assert names == ["v0", "v1"]


# ------------------------------------------------------------------------ --workers


def test_workers_beyond_the_items_and_cpus_are_capped_with_a_note(monkeypatch, tmp_path):
    started = []

    def recording(workers):  # threads stand in for the processes (quicker to start)
        started.append(workers)
        return ThreadPoolExecutor(workers)

    monkeypatch.setattr(batch, "process_pool", recording)
    with pytest.warns(CagekitWarning, match="10000 workers") as notes:
        rows = amplify("synthetic:vases:3", str(tmp_path), variations=2, method="scale",
                       workers=10000)
    assert len([w for w in notes if "workers" in str(w.message)]) == 1
    assert len(rows) == 2 and all(r["status"] != "failed" for r in rows)
    capped = min(2, batch.usable_cores())  # 2 items to do
    assert started == ([] if capped == 1 else [capped])  # 1 runs in this process
    # no note when nothing is cut
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        amplify("synthetic:vases:3", str(tmp_path / "one"), variations=1, method="scale",
                workers=1)
    assert not [w for w in caught if "workers" in str(w.message)]



def test_a_capped_workers_option_is_one_line_on_the_command_line(tmp_path):
    result = cagekit("amplify", "synthetic:vases:3", "-o", tmp_path, "--variations", "1",
                     "--method", "scale", "--workers", "10000")
    assert result.returncode == 0, result.stderr
    notes = [line for line in one_line_messages(result.stderr) if "workers" in line]
    assert len(notes) == 1 and "10000 workers asked for, 1 started" in notes[0]
    assert len(json.loads((tmp_path / "manifest.json").read_text())["items"]) == 1


def no_processes(*args, **kwargs):
    raise BlockingIOError(11, "Resource temporarily unavailable")


@pytest.mark.parametrize("where", ["pool", "spawn"])
def test_workers_that_cannot_start_are_one_line_and_exit_2(monkeypatch, tmp_path, where):
    if where == "pool":  # the pool's pipes and locks
        monkeypatch.setattr(batch.cf, "ProcessPoolExecutor", no_processes)
    else:  # each worker's fork (and the resource tracker's)
        monkeypatch.setattr(multiprocessing.util, "spawnv_passfds", no_processes)
    out = tmp_path / "out"
    result = invoke("amplify", "synthetic:vases:3", "-o", out, "--variations", "2",
                    "--method", "scale", "--workers", "2")
    assert result.exit_code == 2, (result.exit_code, result.output)
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "worker" in lines[0] and "Resource temporarily unavailable" \
        in lines[0], result.stderr
    assert "Traceback" not in result.output


def test_a_local_cluster_gets_no_more_workers_than_cores(monkeypatch):
    distributed = pytest.importorskip("distributed")
    from cagekit.batch.cluster import connect

    made = []

    class Cluster:
        def __init__(self, n_workers, **options):
            made.append(n_workers)

    monkeypatch.setattr(distributed, "LocalCluster", Cluster)
    monkeypatch.setattr(distributed, "Client", lambda cluster: cluster)
    with pytest.warns(CagekitWarning, match="10000 workers asked for"):
        connect("local", workers=10000)
    assert made == [batch.usable_cores()]


# ------------------------------------------------------------------ a worker's warnings


@two_cores
def test_warnings_issued_in_workers_are_one_line_each(two, tmp_path):
    with open(two / "v1.obj", "a") as fh:
        fh.write("l 1 2\n")  # a line element: dropped with a warning each time it is read
    result = cagekit("amplify", two, "-o", tmp_path / "out", "--pairs", "all", "--method",
                     "scale", "--workers", "2")
    assert result.returncode == 0, result.stderr
    dropped = [line for line in one_line_messages(result.stderr) if "dropped" in line]
    assert len(dropped) == 1 and "v1.obj" in dropped[0], result.stderr


# ------------------------------------------------- an interrupted run that finished nothing


def test_an_interrupted_run_that_finished_nothing_leaves_no_folder(flattening, tmp_path,
                                                                   monkeypatch):
    collection, _, _ = flattening

    def interrupted(self, executor, workers):
        raise KeyboardInterrupt

    monkeypatch.setattr(batch._Runner, "run", interrupted)
    fresh = tmp_path / "new" / "out"
    with pytest.raises(KeyboardInterrupt):
        amplify(str(collection), str(fresh), pairs="all", workers=1, method="scale")
    assert not (tmp_path / "new").exists()  # nor the parent the run made
    # a folder that was there before is left as it was, manifest and all
    (tmp_path / "kept").mkdir()
    with pytest.raises(KeyboardInterrupt):
        amplify(str(collection), str(tmp_path / "kept"), pairs="all", workers=1,
                method="scale")
    assert (tmp_path / "kept" / "manifest.json").exists()

    def one_cage_then_interrupted(self, executor, workers):
        (fresh / "cages" / "a-chair.obj").write_text("v 0 0 0\n")  # finished work
        raise KeyboardInterrupt

    monkeypatch.setattr(batch._Runner, "run", one_cage_then_interrupted)
    with pytest.raises(KeyboardInterrupt):
        amplify(str(collection), str(fresh), pairs="all", workers=1, method="scale")
    assert (fresh / "cages" / "a-chair.obj").exists() and (fresh / "manifest.json").exists()

    # items finished without a mesh (failed, or rejected and dropped) are work to keep
    def one_item_then_interrupted(self, executor, workers):
        self.manifest.rows[self.order[0]] = {"source": "a", "target": "b", "status": "failed",
                                             "reason": "no"}
        self.manifest.save(self.order)
        raise KeyboardInterrupt

    monkeypatch.setattr(batch._Runner, "run", one_item_then_interrupted)
    other = tmp_path / "other"
    with pytest.raises(KeyboardInterrupt):
        amplify(str(collection), str(other), pairs="all", workers=1, method="scale")
    assert len(manifest_of(other)["items"]) == 1


def test_a_failed_clean_up_never_hides_the_run_s_own_error(flattening, tmp_path):
    collection, _, _ = flattening
    (tmp_path / "afile").write_text("not a folder")
    result = cagekit("amplify", collection, "-o", tmp_path / "afile" / "out", "--pairs",
                     "all", "--method", "scale")
    assert_bad_input(result, "afile is not a folder")

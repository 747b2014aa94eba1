"""Bad input and hard cases of the command line: a clear line and exit 2, or the
documented result, never a silent wrong one (issue 14)."""

import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
from builders import CAGE, ROOT, SHAPE, assert_bad_input, cagekit

from cagekit import io
from cagekit.cage.shapes import box_cage


def stderr_lines(result):
    return result.stderr.strip().splitlines()


@pytest.fixture
def read_only_folder(tmp_path, read_only):
    folder = tmp_path / "ro"
    folder.mkdir()
    with read_only(folder):
        yield folder


# ------------------------------------------------------------------ points far outside


def test_apply_identity_cage_keeps_far_points_where_they_are(tmp_path):
    """Points too far for MVC follow the cage's affine fit: the rest cage leaves them put
    (they used to land on a cage vertex, at the origin, or 2.48 off at 1e6)."""
    points = np.array([[1e100, 0, 0], [0, 1e200, 0], [1e6, 1, 1], [0.1, 0.2, 0.1],
                       [-3e4, 2e4, 5e3]])
    cloud = tmp_path / "far.xyz"
    io.save_points(cloud, points)
    out = tmp_path / "out.xyz"
    result = cagekit("apply", cloud, CAGE, CAGE, "-o", out, "--allow-outside")  # 80% out
    assert result.returncode == 0, result.stderr
    moved = io.load_points(out)
    scale = np.maximum(np.abs(points).max(axis=1, keepdims=True), 1.0)
    assert np.all(np.abs(moved - points) <= 1e-12 * scale)
    # one warning, with the share outside and how the far ones are treated
    warning = [line for line in stderr_lines(result) if "warning" in line]
    assert len(warning) == 1 and "80% of" in warning[0] and "4 of 5 points" in warning[0]
    assert "affine fit" in warning[0]


def test_points_whose_coordinates_overflow_are_refused(tmp_path):
    v, f = box_cage()
    cage = tmp_path / "tiny_cage.obj"
    io.save_mesh(cage, v * 1e-100, f)
    cloud = tmp_path / "huge.xyz"
    io.save_points(cloud, [[1e300, 0, 0]])
    result = cagekit("apply", cloud, cage, cage, "-o", tmp_path / "o.xyz", "--allow-outside")
    assert_bad_input(result)
    assert "overflow" in result.stderr
    assert not (tmp_path / "o.xyz").exists()


FAR = ("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nv 1e38 0 0\n"
       "f 1 3 2\nf 1 2 4\nf 2 3 4\nf 3 1 4\nf 2 5 4\n")


@pytest.mark.parametrize("role", ["source", "target"])
def test_a_vertex_far_beyond_the_rest_is_refused_before_anything_is_written(tmp_path, role):
    """One vertex at 1e38: the other vertices would collapse in the unit frame (as a
    source, the result had no area; as a target, the source was blown up 1e38 wide and
    the command exited 0). Refused naming the file and the vertex; no output."""
    far = tmp_path / "far.obj"
    far.write_text(FAR)
    chair = os.path.join(ROOT, "data", "example", "chair_target.obj")
    out = tmp_path / "o.obj"
    result = cagekit("deform", *((far, chair) if role == "source" else (chair, far)), "-o", out)
    assert_bad_input(result, str(far))
    assert "vertex 4" in result.stderr and "stray" in result.stderr
    assert not out.exists()


# ------------------------------------------------------------- cages that are not right


def test_deform_with_a_cage_that_does_not_enclose_the_source_warns_with_the_share(tmp_path):
    V, F = io.load_mesh(CAGE)
    small = tmp_path / "small_cage.obj"
    io.save_mesh(small, V * 0.7, F)
    out = tmp_path / "out.obj"
    result = cagekit("deform", SHAPE, os.path.join(ROOT, "data", "example", "chair_target.obj"),
                     "--cage", small, "-o", out)
    assert result.returncode == 0, result.stderr
    warning = [line for line in stderr_lines(result) if "warning" in line]
    assert len(warning) == 1, result.stderr
    # the share outside, naming both files (as apply does)
    assert f"48% of {SHAPE}" in warning[0] and f"outside {small}" in warning[0]
    assert out.exists()


@pytest.fixture
def crossing_cage(tmp_path):
    """The example cage with one vertex pushed through the opposite side."""
    V, F = io.load_mesh(CAGE)
    V = V.copy()
    V[0] = -1.5 * V[0]
    path = tmp_path / "crossing_cage.obj"
    io.save_mesh(path, V, F)
    return path


@pytest.mark.parametrize("command", ["apply", "deform"])
def test_self_intersecting_cage_is_refused_naming_it(tmp_path, crossing_cage, command):
    out = tmp_path / "out.obj"
    if command == "apply":
        result = cagekit("apply", SHAPE, crossing_cage, crossing_cage, "-o", out)
    else:
        target = os.path.join(ROOT, "data", "example", "chair_target.obj")
        result = cagekit("deform", SHAPE, target, "--cage", crossing_cage, "-o", out)
    assert_bad_input(result, crossing_cage)
    assert "intersects itself" in result.stderr and "faces cross" in result.stderr
    assert not out.exists()


# ------------------------------------------------------------------------ option values


@pytest.mark.parametrize("args", [
    ["synth", "chairs", "--resolution", "nan", "-o", "{tmp}/s"],
    ["synth", "chairs", "--resolution", "inf", "-o", "{tmp}/s"],
    ["eval", SHAPE, SHAPE, SHAPE, "--samples", "1000000000"],
    ["synth", "chairs", "-n", "1000000000000", "-o", "{tmp}/s"],
    ["fit-cage", SHAPE, "-o", "{tmp}/c.obj", "--faces", "10000000000"],
], ids=["nan", "inf", "samples", "count", "faces"])
def test_unreasonable_option_values_exit_2(tmp_path, args):
    result = cagekit(*[a.format(tmp=tmp_path) for a in args])
    assert_bad_input(result)
    assert "Invalid value" in result.stderr
    assert os.listdir(tmp_path) == []


def test_synth_under_a_regular_file_exits_2(tmp_path):
    (tmp_path / "file.txt").write_text("not a folder\n")
    result = cagekit("synth", "chairs", "-o", tmp_path / "file.txt" / "shapes")
    assert_bad_input(result, "file.txt")
    assert "not a folder" in result.stderr


def test_synth_into_a_read_only_folder_exits_2_and_leaves_no_folder(read_only_folder):
    result = cagekit("synth", "chairs", "-o", read_only_folder / "new" / "shapes")
    assert_bad_input(result, "shapes")
    result = cagekit("synth", "chairs", "-o", read_only_folder)
    assert_bad_input(result, "chair_0000.obj")
    assert os.listdir(read_only_folder) == []


def test_amplify_into_a_read_only_folder_exits_2(read_only_folder):
    result = cagekit("amplify", "synthetic:vases:2", "-o", read_only_folder / "amp",
                     "--variations", "1")
    assert_bad_input(result, "amp")
    assert "cannot make the folder" in result.stderr
    assert os.listdir(read_only_folder) == []


def test_an_output_that_cannot_be_written_is_refused_before_any_work(read_only_folder,
                                                                     monkeypatch):
    """fit-cage (and every command that writes a file) says so before it fits."""
    from click.testing import CliRunner

    import cagekit.cage.fitting
    from cagekit.cli import main

    def never(*args, **kwargs):
        raise AssertionError("the cage was fitted")

    monkeypatch.setattr(cagekit.cage.fitting, "fit_cage", never)
    result = CliRunner().invoke(main, ["fit-cage", SHAPE, "-o", str(read_only_folder / "c.obj")])
    assert result.exit_code == 2, result.output
    assert f"cannot write in {read_only_folder}" in result.output
    assert os.listdir(read_only_folder) == []


def test_an_interrupt_after_the_first_output_removes_what_the_command_made(tmp_path,
                                                                           monkeypatch):
    """fit-cage writes the cage, then its preview: Ctrl-C while drawing removes the new
    cage file; a cage file it replaced keeps the new cage (its old content is not kept)."""
    from click.testing import CliRunner

    import cagekit.render
    from cagekit.cli import main

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(cagekit.render, "render_meshes", interrupted)
    args = ["fit-cage", SHAPE, "--faces", "60", "--preview", str(tmp_path / "p.png")]
    result = CliRunner().invoke(main, args + ["-o", str(tmp_path / "new.obj")])
    assert result.exit_code == 130
    assert os.listdir(tmp_path) == []
    (tmp_path / "old.obj").write_text("v 0 0 0\n")
    result = CliRunner().invoke(main, args + ["-o", str(tmp_path / "old.obj")])
    assert result.exit_code == 130
    assert os.listdir(tmp_path) == ["old.obj"]
    assert len(io.load_mesh(tmp_path / "old.obj")[1]) > 0  # the new cage


def test_a_finished_commands_outputs_stay_when_its_reader_goes_away(tmp_path):
    """click exits 1 on a closed stdout pipe: the command had finished, its files stay."""
    code = ("import sys; from cagekit.cli import main; "
            f"sys.argv = ['cagekit', 'synth', 'chairs', '-n', '2', '-o', {str(tmp_path / 's')!r}]; "
            "main()")
    proc = subprocess.run(f"{sys.executable} -c \"{code}\" | head -c0", shell=True,
                          env={**os.environ, "PYTHONPATH": ROOT}, capture_output=True,
                          text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert len(os.listdir(tmp_path / "s")) == 2


def test_a_failed_synth_leaves_no_folder_it_made(tmp_path, monkeypatch):
    """A folder the command made is removed when the run fails (here: interrupted)."""
    from click.testing import CliRunner

    import cagekit.datasets.synthetic as synthetic
    from cagekit.cli import main

    def failing(**kwargs):
        raise KeyboardInterrupt

    monkeypatch.setitem(synthetic.FAMILIES, "chairs", failing)
    result = CliRunner().invoke(main, ["synth", "chairs", "-o", str(tmp_path / "a" / "b")])
    assert result.exit_code == 130
    assert not (tmp_path / "a").exists()


# ------------------------------------------------------------------ warnings and signals


def test_library_warnings_are_one_line_each(tmp_path):
    lines = tmp_path / "lines.obj"
    lines.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 2 3 4\n"
                     "f 1 4 3\nf 1 2\nl 1 2\n")
    result = cagekit("render", lines, "-o", tmp_path / "l.png")
    assert result.returncode == 0, result.stderr
    assert stderr_lines(result) == [
        f"cagekit render: warning: {lines}: dropped 1 face(s) with fewer than 3 vertices "
        "(the first at line 9) and 1 line element(s) (the first at line 10); kept 4 face(s)"]


def run_command_doing(statement):
    """Run a one-statement command built with cagekit's Command class, as ``demo``."""
    code = ("import ctypes, warnings, click\n"
            "from cagekit.cli.common import Command\n"
            "@click.command(cls=Command)\n"
            "def cmd():\n"
            f"    {statement}\n"
            "cmd(prog_name='demo')\n")
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          env={**os.environ, "PYTHONPATH": ROOT})


def test_a_foreign_warning_is_one_line_too():
    """Another library's warning (a multi-line UserWarning with its source line, say) is
    one line of ours, naming where it came from."""
    result = run_command_doing("warnings.warn('first line\\nsecond line', UserWarning)")
    assert result.returncode == 0, result.stderr
    assert result.stderr.strip().splitlines() == [
        "demo: warning: first line second line (<string> UserWarning)"]


def test_the_same_warning_from_two_places_is_one_line():
    """A file read twice in one command (for the work, then for a picture) says once what
    it drops; another message still shows."""
    result = run_command_doing(  # three places: Python's own registry would show all
        "[warnings.warn_explicit(m, UserWarning, 'io.py', n) for n, m in "
        "enumerate(('a.obj: dropped 1', 'b.obj: dropped 2', 'a.obj: dropped 1'))]")
    assert result.returncode == 0, result.stderr
    assert result.stderr.strip().splitlines() == [
        "demo: warning: a.obj: dropped 1 (io UserWarning)",
        "demo: warning: b.obj: dropped 2 (io UserWarning)"]


@pytest.mark.parametrize("signum, status, line", [(signal.SIGINT, 130, "interrupted"),
                                                  (signal.SIGTERM, 143, "terminated")])
def test_a_signal_prints_one_line_and_leaves_no_partial_output(tmp_path, signum, status,
                                                               line):
    """Ctrl-C, and SIGTERM (``kill``, ``timeout``) as well."""
    out = tmp_path / "shapes"
    env = {**os.environ, "PYTHONPATH": ROOT}
    proc = subprocess.Popen([sys.executable, "-m", "cagekit.cli", "synth", "chairs", "-n", "500",
                             "-o", str(out)], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, env=env)
    while proc.poll() is None and not (out.is_dir() and len(os.listdir(out)) >= 2):
        time.sleep(0.01)  # wait until it is writing shapes
    proc.send_signal(signum)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == status, err
    assert err.strip().splitlines() == [f"cagekit synth: error: {line}"]
    # the shapes written before the interrupt are removed, and the folder the run made
    assert os.listdir(tmp_path) == []


def test_a_native_crash_is_reported_not_silent():
    """A segmentation fault in compiled code prints the Python call it happened in."""
    result = run_command_doing("ctypes.string_at(0)")
    assert result.returncode == -signal.SIGSEGV
    assert "Segmentation fault" in result.stderr and "in cmd" in result.stderr


# -------------------------------------------------------------------- degenerate meshes


def test_fit_cage_of_a_collinear_mesh_cages_its_segment(tmp_path):
    """All faces of zero area: a cage around the segment (it used to crash, exit 139)."""
    mesh = tmp_path / "collinear.obj"
    mesh.write_text("v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n")
    result = cagekit("fit-cage", mesh, "-o", tmp_path / "c.obj", "--json")
    assert result.returncode == 0, result.stderr
    assert '"ok": true' in result.stdout


def test_deform_of_a_collinear_source_exits_2(tmp_path):
    mesh = tmp_path / "collinear.obj"
    mesh.write_text("v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n")
    result = cagekit("deform", mesh, SHAPE, "-o", tmp_path / "o.obj")
    assert_bad_input(result, "collinear.obj")
    assert "zero total area" in result.stderr and "shape.obj" not in result.stderr

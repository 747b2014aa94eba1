"""The Blender add-on (apps/blender/cagekit_blender) with the real bpy (make test-blender).

Every test starts from an empty scene. Blender keeps coordinates in float32: a mesh moved by
its cage must equal cagekit's float64 result rounded to float32.
"""

import sys
from pathlib import Path

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "apps" / "blender"))

import cagekit_blender  # noqa: E402
from cagekit_blender import live, meshes  # noqa: E402

import cagekit  # noqa: E402
from cagekit import io  # noqa: E402

pytestmark = pytest.mark.blender

DATA = Path(__file__).resolve().parents[2] / "data" / "example"


@pytest.fixture(scope="module", autouse=True)
def addon():
    cagekit_blender.register()
    yield
    cagekit_blender.unregister()


@pytest.fixture(autouse=True)
def empty_scene():
    bpy.ops.wm.read_factory_settings(use_empty=True)
    live._runtime.clear()


def _object(name, V, F):
    return meshes.new_object(name, V, F, bpy.context.scene.collection)


def _select(selected, active):
    for o in bpy.context.view_layer.objects:
        o.select_set(False)
    for o in selected + [active]:
        o.select_set(True)
    bpy.context.view_layer.objects.active = active


def _shape_and_cage():
    """The bundled example shape and cage, the shape moved off the origin by its object
    matrix (bindings work in world space)."""
    shape = _object("shape", *io.load_mesh(DATA / "shape.obj"))
    shape.location = (0.3, -0.2, 0.1)
    shape.rotation_euler = (0.0, 0.0, 0.5)
    cage_v, cage_f = io.load_mesh(DATA / "cage.obj")
    cage = _object("cage", meshes.from_world(meshes.to_world(cage_v, _matrix(shape)),
                                             np.eye(4)), cage_f)
    bpy.context.view_layer.update()
    return shape, cage


def _matrix(obj):
    bpy.context.view_layer.update()
    return meshes.matrix(obj)


def _move_cage(cage, seed=0, amount=0.15):
    V = meshes.local_vertices(cage)
    V += np.random.default_rng(seed).normal(scale=amount, size=V.shape)
    cage.data.vertices.foreach_set("co", V.astype(np.float32).ravel())
    cage.data.update()
    bpy.context.view_layer.update()


def _expected(shape, cage, coords):
    """cagekit's own result for the stored rest state, in float32 (the mesh's own space)."""
    rest, rest_cage, _ = live.rest_state(shape)
    b = cagekit.bind(rest, rest_cage, meshes.triangles(cage), method=coords)
    return np.float32(meshes.from_world(b.deform(meshes.world_vertices(cage)),
                                        meshes.matrix(shape)))


def _run(op, **kw):
    """Run an operator as a script does: a reported error raises RuntimeError."""
    return getattr(bpy.ops.cagekit, op)(**kw)


def test_registers_every_operator_and_the_panel():
    for name in ("fit_cage", "bind", "unbind", "deform_to_target", "transfer_pose",
                 "amplify"):
        assert hasattr(bpy.types, f"CAGEKIT_OT_{name}"), name
    assert hasattr(bpy.types, "CAGEKIT_PT_panel")
    assert bpy.types.Scene.bl_rna.properties.get("cagekit") is not None


def test_fit_cage_makes_a_wire_cage_that_encloses_the_mesh():
    shape = _object("chair", *io.load_mesh(DATA / "chair_source.obj"))
    _select([], shape)
    assert _run("fit_cage", faces=120) == {"FINISHED"}
    cage = bpy.data.objects["chair_cage"]
    assert cage.display_type == "WIRE" and bpy.context.active_object == cage
    cv, cf = meshes.world_mesh(cage, "cage")
    assert len(cf) <= 120
    assert cagekit.cage_encloses(meshes.world_vertices(shape), cv, cf)


@pytest.mark.parametrize("coords", ["mvc", "green"])
def test_editing_the_cage_moves_the_mesh_as_cagekit_does(coords):
    shape, cage = _shape_and_cage()
    _select([shape], cage)
    assert _run("bind", coords=coords) == {"FINISHED"}
    assert live.is_bound(shape) and shape.cagekit_cage == cage
    rest_local = meshes.local_vertices(shape)
    for seed in range(3):  # object-mode edits of the cage's vertices
        _move_cage(cage, seed)
        got = meshes.local_vertices(shape)
        assert np.abs(got - _expected(shape, cage, coords)).max() <= 1e-9
        assert np.abs(got - rest_local).max() > 1e-3
    # moving the cage object (its matrix) moves the mesh too
    cage.location = (0.0, 0.0, 1.0)
    bpy.context.view_layer.update()
    np.testing.assert_allclose(meshes.local_vertices(shape), _expected(shape, cage, coords),
                               atol=1e-9)


def test_edit_mode_edits_move_the_mesh_live():
    import bmesh

    shape, cage = _shape_and_cage()
    _select([shape], cage)
    _run("bind")
    _select([], cage)  # the cage alone in edit mode (a mesh in edit mode is left alone)
    bpy.ops.object.mode_set(mode="EDIT")
    bm = bmesh.from_edit_mesh(cage.data)
    bm.verts.ensure_lookup_table()
    bm.verts[0].co.x += 0.3
    bmesh.update_edit_mesh(cage.data)
    bpy.context.view_layer.update()
    assert cage.mode == "EDIT"
    got = meshes.local_vertices(shape)
    assert np.abs(got - _expected(shape, cage, "mvc")).max() <= 1e-9
    bpy.ops.object.mode_set(mode="OBJECT")


def test_unbind_gives_the_rest_shape_back_and_undo_rebinds():
    shape, cage = _shape_and_cage()
    rest = meshes.local_vertices(shape)
    _select([shape], cage)
    _run("bind")
    _move_cage(cage)
    bpy.ops.ed.undo_push(message="cage moved")
    _select([shape], shape)
    assert _run("unbind") == {"FINISHED"}
    assert not live.is_bound(shape) and shape.cagekit_cage is None
    np.testing.assert_array_equal(meshes.local_vertices(shape), rest)
    bpy.ops.ed.undo_push(message="unbound")  # as Blender's UI does after an operator
    bpy.ops.ed.undo()  # the binding and the moved mesh come back
    bpy.context.view_layer.update()
    shape, cage = bpy.data.objects["shape"], bpy.data.objects["cage"]
    assert live.is_bound(shape)
    _move_cage(cage, seed=5)
    assert np.abs(meshes.local_vertices(shape) - _expected(shape, cage, "mvc")).max() <= 1e-9


def test_undoing_a_cage_edit_moves_the_mesh_back():
    shape, cage = _shape_and_cage()
    _select([shape], cage)
    _run("bind", coords="green")
    bpy.ops.ed.undo_push(message="bound")
    before = meshes.local_vertices(shape)
    _move_cage(cage, seed=1)
    bpy.ops.ed.undo_push(message="cage moved")
    assert np.abs(meshes.local_vertices(shape) - before).max() > 1e-3
    bpy.ops.ed.undo()
    bpy.context.view_layer.update()  # as the redraw after an undo does
    shape = bpy.data.objects["shape"]
    np.testing.assert_allclose(meshes.local_vertices(shape), before, rtol=0, atol=1e-9)


def test_the_binding_survives_saving_and_reopening(tmp_path):
    shape, cage = _shape_and_cage()
    _select([shape], cage)
    _run("bind", coords="green")
    _move_cage(cage, seed=2)
    moved = meshes.local_vertices(shape)
    path = tmp_path / "bound.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    bpy.ops.wm.read_factory_settings(use_empty=True)
    live._runtime.clear()
    bpy.ops.wm.open_mainfile(filepath=str(path))
    bpy.context.view_layer.update()
    shape, cage = bpy.data.objects["shape"], bpy.data.objects["cage"]
    assert live.is_bound(shape) and shape[live.COORDS] == "green"
    np.testing.assert_array_equal(meshes.local_vertices(shape), moved)
    _move_cage(cage, seed=3)  # recomputed from the stored rest state, as at bind time
    assert np.abs(meshes.local_vertices(shape) - _expected(shape, cage, "green")).max() <= 1e-9


def _assert_one_line_error(op, match, **kw):
    with pytest.raises(RuntimeError) as err:
        _run(op, **kw)
    text = str(err.value).strip()
    assert "\n" not in text and "Traceback" not in text, text
    assert match in text, text


def test_a_cage_that_is_not_a_mesh_is_one_line_and_changes_nothing():
    shape, _ = _shape_and_cage()
    bpy.ops.object.camera_add()
    camera = bpy.context.active_object
    _select([shape], camera)
    before = meshes.local_vertices(shape)
    _assert_one_line_error("bind", "the cage 'Camera' is a camera, not a mesh")
    assert not live.is_bound(shape) and "cagekit_rest" not in shape
    np.testing.assert_array_equal(meshes.local_vertices(shape), before)


def test_an_open_cage_is_one_line_naming_it_and_changes_nothing():
    shape, cage = _shape_and_cage()
    V, F = meshes.local_vertices(cage), meshes.triangles(cage)
    open_cage = _object("open", V, F[1:])
    _select([shape], open_cage)
    _assert_one_line_error("bind", "cage 'open'")
    assert not live.is_bound(shape)
    _select([], bpy.data.objects["open"])
    _assert_one_line_error("unbind", "no bound mesh selected")


def test_deform_to_target_makes_a_new_object_and_its_cage():
    source = _object("src", *io.load_mesh(DATA / "chair_source.obj"))
    target = _object("tgt", *io.load_mesh(DATA / "chair_target.obj"))
    before = meshes.local_vertices(source)
    _select([source], target)
    assert _run("deform_to_target", symmetry="x", evaluations=15) == {"FINISHED"}
    out, cage = bpy.data.objects["src_deformed"], bpy.data.objects["src_deformed_cage"]
    start = bpy.data.objects["src_cage"]  # the cage fitted for it, as it started
    assert cage.display_type == "WIRE" == start.display_type
    np.testing.assert_array_equal(meshes.local_vertices(source), before)  # input untouched
    expected = cagekit.deform(*meshes.world_mesh(source, "s"), *meshes.world_mesh(target, "t"),
                              options=cagekit.DeformOptions(symmetry="x", max_evaluations=15))
    np.testing.assert_allclose(meshes.local_vertices(out), np.float32(expected.vertices),
                               atol=1e-5)
    np.testing.assert_allclose(meshes.local_vertices(start), np.float32(expected.cage_v),
                               atol=1e-6)
    assert len(out.data.polygons) == len(source.data.polygons)  # a copy: quads kept


def test_deform_to_target_starts_from_a_given_cage():
    shape, cage = _shape_and_cage()
    target = _object("tgt", *io.load_mesh(DATA / "chair_target.obj"))
    _select([shape], target)
    assert _run("deform_to_target", cage="cage", evaluations=5) == {"FINISHED"}
    assert "shape_cage" not in bpy.data.objects  # nothing fitted
    result = cagekit.deform(*meshes.world_mesh(shape, "s"), *meshes.world_mesh(target, "t"),
                            *meshes.world_mesh(cage, "c"),
                            options=cagekit.DeformOptions(max_evaluations=5))
    np.testing.assert_allclose(meshes.local_vertices(bpy.data.objects["shape_deformed_cage"]),
                               np.float32(result.deformed_cage_v), atol=1e-6)


def test_deform_needs_one_source_and_a_target():
    source = _object("src", *io.load_mesh(DATA / "chair_source.obj"))
    _select([], source)
    _assert_one_line_error("deform_to_target", "select the source too")


@pytest.mark.parametrize("landmarks", ["groups", "files"])
def test_transfer_pose_with_landmarks_from_vertex_groups_or_files(tmp_path, landmarks):
    from builders import small_humanoid_data

    from cagekit.io.landmarks import load_landmarks
    from cagekit.transfer import character as dt

    small_humanoid_data(tmp_path)
    files = [tmp_path / "template_landmarks.json",
             tmp_path / "characters" / "stocky_landmarks.json"]
    template = _object("template", *io.load_mesh(tmp_path / "template.obj"))
    _object("template_cage", *io.load_mesh(tmp_path / "template_cage.obj"))
    character = _object("stocky", *io.load_mesh(tmp_path / "characters" / "stocky.obj"))
    poses = bpy.data.collections.new("poses")
    bpy.context.scene.collection.children.link(poses)
    pose_files = sorted((tmp_path / "poses").glob("pose_???.obj"))
    for path in pose_files:
        meshes.new_object(path.stem, *io.load_mesh(path), poses)
    if landmarks == "groups":
        for obj, path in zip((template, character), files):
            V = meshes.world_vertices(obj)
            for label, point in load_landmarks(path).items():  # each landmark's nearest vertex
                group = obj.vertex_groups.new(name=label)
                group.add([int(np.argmin(np.linalg.norm(V - point, axis=1)))], 1.0, "REPLACE")
    assert _run("transfer_pose", template="template", template_cage="template_cage",
                poses="poses", character="stocky", landmarks=landmarks,
                template_landmarks=str(files[0]), character_landmarks=str(files[1])) \
        == {"FINISHED"}
    out = bpy.data.collections["stocky_poses"]
    assert {o.name for o in out.objects} == {"stocky_cage"} | {f"stocky_{p.stem}"
                                                               for p in pose_files}
    Vc, Fc = io.load_mesh(tmp_path / "characters" / "stocky.obj")
    for path in pose_files:  # the ground truth is reached as by cagekit transfer
        truth = io.load_mesh(tmp_path / "truth" / "stocky" / path.name)[0]
        got = meshes.world_vertices(bpy.data.objects[f"stocky_{path.stem}"])
        rest = np.linalg.norm(Vc - truth, axis=1).mean()
        assert np.linalg.norm(got - truth, axis=1).mean() < rest / 3, path.stem
    if landmarks == "files":  # the library's own result, to float32
        template_mesh = io.load_mesh(tmp_path / "template.obj")
        cage = io.load_mesh(tmp_path / "template_cage.obj")
        char = dt.fit_character(template_mesh[0], *cage, load_landmarks(files[0]), Vc, Fc,
                                load_landmarks(files[1]))
        pose = io.load_mesh(pose_files[0])
        expected = dt.transfer(char, dt.template_cage_classical(*template_mesh, *cage, *pose))
        got = meshes.world_vertices(bpy.data.objects[f"stocky_{pose_files[0].stem}"])
        np.testing.assert_allclose(got, np.float32(expected), atol=1e-5)


def test_transfer_names_a_missing_object():
    _assert_one_line_error("transfer_pose", "template 'nobody' is not an object",
                           template="nobody")


def test_amplify_makes_accepted_variations_into_a_new_collection():
    from cagekit.datasets.synthetic import vase

    coll = bpy.data.collections.new("vases")
    bpy.context.scene.collection.children.link(coll)
    for i in range(3):
        meshes.new_object(f"vase.{i:03d}", *vase(seed=i, resolution=0.5), coll)
    assert _run("amplify", collection="vases", variations=2) == {"FINISHED"}
    out = bpy.data.collections["vases_variations"]
    assert 1 <= len(out.objects) <= 2
    for obj in out.objects:
        source_name = obj.name.split("__")[0]
        assert len(obj.data.vertices) == len(bpy.data.objects[source_name].data.vertices)
        assert np.abs(meshes.world_vertices(obj)
                      - meshes.world_vertices(bpy.data.objects[source_name])).max() > 1e-3


def test_amplify_needs_two_meshes():
    coll = bpy.data.collections.new("lonely")
    bpy.context.scene.collection.children.link(coll)
    meshes.new_object("one", *io.load_mesh(DATA / "shape.obj"), coll)
    _assert_one_line_error("amplify", "needs at least 2 meshes", collection="lonely")


def test_progress_reports_and_cancels_between_steps():
    from cagekit_blender.jobs import Cancelled, Progress

    progress = Progress()
    progress(2, 4, "variations")
    assert progress.text("making variations") == ("cagekit: making variations 50% "
                                                  "variations (Esc to cancel)")
    progress.cancel()
    with pytest.raises(Cancelled):
        progress(3, 4)
    assert progress.done == 2  # nothing recorded after the cancel


def test_a_deleted_bound_mesh_frees_its_binding_and_its_name_is_not_confused():
    shape, cage = _shape_and_cage()
    _select([shape], cage)
    _run("bind")
    _move_cage(cage, amount=0.01)
    assert "shape" in live._runtime
    bpy.data.objects.remove(shape)
    _move_cage(cage, seed=1, amount=0.01)
    assert "shape" not in live._runtime  # dropped at the next update
    # a new mesh under the old name, bound to the same cage, gets its own binding
    other = _object("shape", *io.load_mesh(DATA / "shape.obj"))
    other.scale = (0.5, 0.5, 0.5)
    bpy.context.view_layer.update()
    _select([other], cage)
    _run("bind", coords="green")
    _move_cage(cage, seed=2, amount=0.01)
    got = meshes.local_vertices(other)
    assert np.abs(got - _expected(other, cage, "green")).max() <= 1e-9


def test_the_panel_draws_and_fills_the_operators_from_the_scene_settings():
    from types import SimpleNamespace
    from unittest import mock

    from cagekit_blender.panel import CAGEKIT_PT_panel

    shape, cage = _shape_and_cage()
    _select([shape], cage)
    _run("bind")
    coll = bpy.data.collections.new("things")
    settings = bpy.context.scene.cagekit
    settings.template, settings.collection, settings.variations = shape, coll, 7
    _select([], shape)
    layout = mock.MagicMock()
    operators = {}
    layout.column.return_value.operator.side_effect = (
        lambda name: operators.setdefault(name, SimpleNamespace()))
    CAGEKIT_PT_panel.draw(SimpleNamespace(layout=layout), bpy.context)
    assert {"cagekit.fit_cage", "cagekit.deform_to_target", "cagekit.transfer_pose",
            "cagekit.amplify"} <= set(operators)
    assert operators["cagekit.transfer_pose"].template == "shape"
    assert operators["cagekit.transfer_pose"].character == ""
    assert (operators["cagekit.amplify"].collection, operators["cagekit.amplify"].variations) \
        == ("things", 7)
    labels = [c.kwargs.get("text", "") for c in layout.column.return_value.label.call_args_list]
    assert "shape: bound to cage (mvc)" in labels


class _FakeJob:
    """A :class:`cagekit_blender.jobs.Job` outside Blender's operator machinery, with a
    computation that waits for a gate, so the modal path can be driven step by step."""

    def __init__(self, gate):
        import threading

        self.gate, self.applied, self.reports = gate, [], []
        self.started = threading.Event()

    def gather(self, context):
        return 21

    def compute(self, inputs, progress):
        progress(1, 2, "halfway")
        self.started.set()
        self.gate.wait(10)
        progress(2, 2)  # raises Cancelled once Esc was pressed
        return 2 * inputs

    def apply(self, context, result):
        self.applied.append(result)

    def report(self, kind, text):
        self.reports.append((kind, text))


def _fake_context():
    from types import SimpleNamespace
    from unittest import mock

    return SimpleNamespace(window_manager=mock.MagicMock(), window=None,
                           workspace=mock.MagicMock())


def _modal_job(gate):
    from cagekit_blender.jobs import Job

    cls = type("Job", (_FakeJob, Job), {"label": "testing"})
    return cls(gate)


def test_the_modal_path_shows_progress_then_applies_in_the_main_thread():
    import threading
    from types import SimpleNamespace

    gate, context = threading.Event(), _fake_context()
    job = _modal_job(gate)
    assert job.invoke(context, None) == {"RUNNING_MODAL"}
    job.started.wait(10)
    timer = SimpleNamespace(type="TIMER")
    assert job.modal(context, timer) == {"RUNNING_MODAL"} and job.applied == []
    context.workspace.status_text_set.assert_called_with(
        "cagekit: testing 50% halfway (Esc to cancel)")
    assert job.modal(context, SimpleNamespace(type="MOUSEMOVE")) == {"PASS_THROUGH"}
    gate.set()
    job._thread.join(10)
    assert job.modal(context, timer) == {"FINISHED"} and job.applied == [42]
    context.workspace.status_text_set.assert_called_with(None)


def test_esc_cancels_and_nothing_is_applied():
    import threading
    from types import SimpleNamespace

    gate, context = threading.Event(), _fake_context()
    job = _modal_job(gate)
    job.invoke(context, None)
    job.started.wait(10)
    assert job.modal(context, SimpleNamespace(type="ESC")) == {"CANCELLED"}
    gate.set()
    job._thread.join(10)
    assert job.applied == [] and "cancelled" in job.reports[-1][1]
    from cagekit_blender.jobs import Cancelled

    assert isinstance(job._outcome["error"], Cancelled)

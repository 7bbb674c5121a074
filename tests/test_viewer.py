"""The browser replay: timeline, decimation, capture groups, colours, the mouth panel against
bulletnet.analysis.metrics, what a new frame sends, the CLI's errors, the HTML export and its index.
Browser checks are in test_viewer_browser.py."""

from __future__ import annotations

import h5py
import numpy as np
import pytest

import bulletnet as bn
from bulletnet.viewer import load_replay, viser_server
from bulletnet.viewer.panel import Panel
from bulletnet.viewer.replay import SLACK, thread_colours

pytest.importorskip("viser")


@pytest.fixture
def runs(viewer_runs):
    return viewer_runs


def test_timeline_shows_each_recordings_last_frame_at_or_before(runs):
    # reference: the definition of the shared timeline, on two record rates (100 and 50 Hz)
    replay = load_replay([runs["plain"], runs["bending"]])
    plain, bending = replay.tracks
    np.testing.assert_array_equal(replay.time, np.union1d(plain.time, bending.time))
    for track, index in zip(replay.tracks, replay.index, strict=True):
        shown = track.time[index]
        assert np.all(shown <= replay.time + 1e-12)
        later = np.minimum(index + 1, track.time.size - 1)
        assert np.all((track.time[later] > replay.time) | (index == track.time.size - 1))
    assert replay.has_bending and not replay.has_debris and not replay.has_contacts


def test_decimation_keeps_every_nth_frame_and_the_last(runs):
    # reference: the recording's own arrays at the kept frames
    rec = bn.open_recording(runs["plain"])
    track = load_replay([runs["plain"]], every=4).tracks[0]
    kept = sorted(set(range(0, rec.time.size, 4)) | {rec.time.size - 1})
    np.testing.assert_array_equal(track.time, rec.time[kept])
    np.testing.assert_array_equal(track.position, rec.position[kept])
    np.testing.assert_array_equal(track.tension, rec.tension[kept])
    np.testing.assert_array_equal(track.utilisation,
                                  rec.tension[kept] / rec.breaking_tension)
    np.testing.assert_array_equal(track.area, bn.metrics.mouth_area(rec)[kept])


def test_capture_groups_pose_matches_the_recorded_quaternion(runs):
    # reference: scipy's reading of the recorded x, y, z, w quaternion; the viewer hands viser
    # w, x, y, z, so viser's rotation of the mesh must be the same matrix
    from scipy.spatial.transform import Rotation
    from viser.transforms import SO3

    track = load_replay([runs["capture"]]).tracks[0]
    with h5py.File(runs["capture"]) as f:
        xyzw, pos = f["debris/orientation"][()], f["debris/position"][()]
        vertices = f["debris/mesh_vertices"][()]
    for k in (0, len(xyzw) // 2, len(xyzw) - 1):
        world = pos[k] + Rotation.from_quat(xyzw[k]).apply(vertices)
        ours = track.debris.position[k] + vertices @ SO3(track.debris.wxyz[k]).as_matrix().T
        np.testing.assert_allclose(ours, world, atol=1e-12)
    assert track.contacts.count.max() > 0


def test_camera_frames_the_capture_and_the_whole_deployment(runs):
    # reference: the recordings' own arrays, the debris mesh placed by scipy's reading of the
    # recorded quaternion; a capture is framed up to its last frame in contact, a recording
    # without contact over all its frames
    from scipy.spatial.transform import Rotation

    replay = load_replay([runs["capture"], runs["plain"]])
    lo, hi = replay.view_box()
    rec, plain = bn.open_recording(runs["capture"]), bn.open_recording(runs["plain"])
    last = int(np.flatnonzero(rec.contacts["count"] > 0)[-1])
    d = rec.debris
    meshes = np.concatenate([d["position"][k] + Rotation.from_quat(d["orientation"][k]).apply(
        d["mesh_vertices"]) for k in range(rec.time.size)])
    for points in (rec.position[:last + 1].reshape(-1, 3), plain.position.reshape(-1, 3),
                   meshes):
        assert np.all(points >= lo - 1e-12) and np.all(points <= hi + 1e-12)
    # the documented definition; the replay keeps the mesh in float32 (as viser draws it), so
    # the debris' reach is the recorded one to float32's rounding (2^-24 relative)
    reach = np.linalg.norm(d["mesh_vertices"], axis=1).max()
    points = np.concatenate([rec.position[:last + 1].reshape(-1, 3), plain.position.reshape(
        -1, 3), d["position"] - reach, d["position"] + reach])
    np.testing.assert_allclose(lo, points.min(axis=0), rtol=0, atol=2.0**-24 * reach)
    np.testing.assert_allclose(hi, points.max(axis=0), rtol=0, atol=2.0**-24 * reach)
    lo, hi = load_replay([runs["plain"]]).view_box()
    np.testing.assert_array_equal(lo, plain.position.min(axis=(0, 1)))
    np.testing.assert_array_equal(hi, plain.position.max(axis=(0, 1)))


def test_thread_colours_slack_grey_and_darker_with_tension():
    # reference: the documented colour law (slack grey, monotone towards the dark shade)
    force = np.array([0.0, 0.01, 0.1, 0.5, 1.0, 3.0])
    rgb = thread_colours(force, 1.0, (31, 119, 180))[:, 0].astype(int)
    assert tuple(rgb[0]) == SLACK
    brightness = rgb[1:].sum(axis=1)
    assert np.all(np.diff(brightness[:-1]) < 0)
    np.testing.assert_array_equal(rgb[-1], rgb[-2])  # saturates at the scale


def _invert(axes, xy):
    left, top, w, h = axes.box
    x = axes.xlim[0] + (xy[:, 0] - left) / w * (axes.xlim[1] - axes.xlim[0])
    y = axes.ylim[0] + (top + h - xy[:, 1]) / h * (axes.ylim[1] - axes.ylim[0])
    return np.stack([x, y], axis=1)


def test_mouth_panel_draws_bulletnet_metrics(runs):
    # reference: bulletnet.analysis.metrics (mouth polygon, area, height) at the panel's frame
    replay = load_replay([runs["plain"], runs["bending"]])
    panel = Panel(replay, [0.1, 0.2])
    k = replay.time.size // 2
    update = panel.updates(k)
    pixel = (panel.mouth_axes.xlim[1] - panel.mouth_axes.xlim[0]) / panel.mouth_axes.box[2]
    for r, path in enumerate((runs["plain"], runs["bending"])):
        rec = bn.open_recording(path)
        j = int(np.argmin(np.abs(rec.time - replay.time[k])))
        xy = np.array([p.split(",") for p in update[f"mouth-{r}"]["points"].split()], float)
        np.testing.assert_allclose(_invert(panel.mouth_axes, xy), bn.metrics.mouth(rec)[j],
                                   atol=0.06 * pixel)  # coordinates printed to 0.1 px
        area = float(update["value-area"]["text"].split(" / ")[r].split()[0])
        assert area == pytest.approx(bn.metrics.mouth_area(rec)[j], rel=1e-3)  # 3 digits
    svg = panel.svg(k)
    assert svg.count('class="snapshot"') == 2 * 2 and 'id="mouth-1"' in svg


def test_panel_plots_the_capture_score_and_names_the_outcome(runs):
    # reference: bulletnet.analysis.metrics.capture_outcome on the recording; a deployment has none
    replay = load_replay([runs["capture"], runs["plain"]])
    panel = Panel(replay, [0.5])
    scores, judged = bn.metrics.capture_outcome(bn.open_recording(runs["capture"]))
    k = replay.time.size - 1
    quality, none = panel.updates(k)["value-quality"]["text"].split(" / ")
    assert float(quality) == pytest.approx(scores[replay.index[0, k], 2], abs=5e-4)
    assert none.startswith("-")
    assert judged.outcome in panel.svg(k) and replay.tracks[1].score is None


def test_a_new_frame_sends_only_what_moved(runs):
    # reference: the static geometry (sphere and debris meshes, radii) was sent once; a frame
    # change may only update props, and showing the same frame sends nothing
    from bulletnet.viewer.server import LiveViewer

    replay = load_replay([runs["capture"], runs["bending"]])
    with viser_server() as server:
        viewer = LiveViewer(server, replay, [0.1])
        sent = []
        queue = server._websock_server.queue_message
        server._websock_server.queue_message = lambda m: (sent.append(m), queue(m))
        viewer.goto(5)
        kinds = {type(m).__name__ for m in sent}
        assert kinds and all(k.endswith("UpdateMessage") or k.startswith("SetPosition")
                             or k.startswith("SetOrientation") for k in kinds), kinds
        assert not any("vertices" in getattr(m, "updates", {}) for m in sent)
        sent.clear()
        viewer.goto(5)
        assert sent == []
        # hidden parts are not sent, and are brought up to date when shown again
        viewer._show("trails", False)
        sent.clear()
        viewer.goto(9)
        assert not any(getattr(m, "name", "").endswith("/trails") for m in sent)
        viewer._show("trails", True)
        layer = viewer.layers[0]
        last_mass = layer.track.position[replay.index[0, 9], layer.track.corner_masses[-1]]
        assert layer.trails.points[-1, 1] == pytest.approx(last_mass)
        assert set(viewer.controls) == {"nodes", "threads", "trails", "debris",
                                        "thread colour", "contacts"}


def test_missing_groups_hide_their_controls(runs):
    from bulletnet.viewer.server import LiveViewer

    with viser_server() as server:
        viewer = LiveViewer(server, load_replay([runs["plain"]]), [0.1])
        assert set(viewer.controls) == {"nodes", "threads", "trails", "thread colour"}
        assert viewer.controls["thread colour"].options == ("tension", "utilisation")


def cli(capsys, *args):
    """``bulletnet view ARGS`` in this process: (exit code, stdout, stderr)."""
    from bulletnet.cli.main import main

    try:
        code = main(["view", *map(str, args)])
    except SystemExit as exc:  # argparse
        code = exc.code
    out, err = capsys.readouterr()
    return code, out, err


def test_view_bad_input_is_one_line(runs, tmp_path, capsys):
    broken = tmp_path / "broken.h5"
    broken.write_bytes(runs["capture"].read_bytes())
    with h5py.File(broken, "r+") as f:
        del f["debris/mesh_faces"]
        f["debris/mesh_faces"] = np.array([[0, 1, len(f["debris/mesh_vertices"])]])
    no_pose = tmp_path / "no_pose.h5"
    no_pose.write_bytes(runs["capture"].read_bytes())
    with h5py.File(no_pose, "r+") as f:
        del f["debris/orientation"]
    existing = tmp_path / "exists.html"
    existing.write_text("x")
    cases = [([str(tmp_path / "missing.h5")], "no such recording"),
             ([str(runs["plain"]), "--every", "0"], "--every"),
             ([str(runs["plain"]), "--port", "70000"], "--port"),
             ([str(runs["plain"])] * 5, "1 to 4 recordings"),
             ([str(broken), "--html", str(tmp_path / "b.html")], "not a triangle mesh"),
             ([str(no_pose)], "damaged capture groups"),
             ([str(runs["plain"]), "--html", str(existing)], "--force"),
             ([str(runs["plain"]), "--html", str(existing / "x.html")], "cannot create")]
    for args, message in cases:
        code, _, err = cli(capsys, *args)
        assert code == 2, (args, err)
        assert message in err and err.count("\n") == 1, err


def test_html_export_and_index(runs, tmp_path, capsys):
    # reference: the export's frame count is the replay's, and the index lists each replay;
    # the folder is created
    out = tmp_path / "replays" / "capture.html"
    code, printed, err = cli(capsys, runs["capture"], runs["bending"], "--html", out,
                             "--every", "2")
    assert code == 0 and printed.strip() == str(out), err
    page = out.read_text()
    replay = load_replay([runs["capture"], runs["bending"]], every=2)
    assert "__VISER_EMBED_DATA__" in page and "bulletnet-panel" in page
    assert f'&quot;frames&quot;: {replay.time.size}' in page
    assert cli(capsys, runs["plain"], "--html", out.parent / "plain.html")[0] == 0
    index = (out.parent / "index.html").read_text()
    assert 'href="capture.html"' in index and 'href="plain.html"' in index


def _polylines(svg: str) -> list[np.ndarray]:
    """The points of every ``<polyline>`` in ``svg``, in order [px], each shape (n, 2)."""
    import re

    return [np.array([p.split(",") for p in points.split()], float)
            for points in re.findall(r'<polyline points="([^"]*)"', svg)]


def test_tow_panel_draws_metrics_tow_series_and_outcome(viewer_tow):
    # reference: bulletnet.analysis.metrics.tow_series and tow_outcome on the recording
    from bulletnet.viewer.panel import TowPanel

    rec = bn.open_recording(viewer_tow)
    series, judged = bn.metrics.tow_series(rec), bn.metrics.tow_outcome(rec)
    replay = load_replay([viewer_tow])
    panel = TowPanel(replay)
    svg = panel.svg(0)
    names = ("thrust", "tension", "distance", "enclosed")
    assert [plot.name for plot, _ in panel.time_axes] == list(names)
    assert panel.time_axes[0][1].xlim == (series["time"][0], rec.time[-1])
    for (_, axes), xy, name in zip(panel.time_axes, _polylines(svg), names, strict=True):
        pixel = np.array([(axes.xlim[1] - axes.xlim[0]) / axes.box[2],
                          (axes.ylim[1] - axes.ylim[0]) / axes.box[3]])
        np.testing.assert_allclose(_invert(axes, xy),  # coordinates printed to 0.1 px
                                   np.stack([series["time"], series[name]], axis=1),
                                   rtol=0, atol=0.06 * pixel.max())
    # the safe distance and the slip threshold dotted, at the recording's [tow] rules
    for name, level in (("distance", judged.rules.safe_distance),
                        ("enclosed", judged.rules.enclosed_fraction)):
        plot, axes = next(p for p in panel.time_axes if p[0].name == name)
        assert plot.levels[0][0] == level
        assert f'y1="{axes(0.0, level)[1]:.1f}"' in svg
    assert f"tow {judged.outcome} at {judged.time:.1f} s" in svg
    # the current values: none before the burn (cursor hidden), the series' at each frame after
    before = panel.updates(0)
    assert before["cursor-thrust"]["visibility"] == "hidden"
    assert before["value-tension"]["text"] == "- [N]"
    for k in np.flatnonzero(replay.time >= series["time"][0]):
        update, i = panel.updates(k), int(np.searchsorted(series["time"], replay.time[k]))
        assert update["cursor-tension"]["visibility"] == "visible"
        for name, digits in zip(names, (0, 0, 1, 3), strict=True):
            # printed to `digits` decimals: within half a unit of the last (and round-off)
            value = float(update[f"value-{name}"]["text"].split()[0])
            assert value == pytest.approx(series[name][i], abs=0.5 * 10.0**-digits + 1e-12)


def test_chaser_drawn_as_a_cube_with_its_thrust_arrow(viewer_tow):
    # reference: the recording's last node (the chaser), the frames' thrust of
    # metrics.tow_series and the recorded scene's thrust direction
    from bulletnet.model.net import NodeKind
    from bulletnet.viewer.replay import CHASER_SIZE, THRUST_LENGTH, thrust_arrow
    from bulletnet.viewer.server import LiveViewer

    rec = bn.open_recording(viewer_tow)
    series = bn.metrics.tow_series(rec)
    direction = np.asarray(bn.metrics.recorded_scene(rec).thrust.direction, float)
    direction /= np.linalg.norm(direction)
    replay = load_replay([viewer_tow])
    track = replay.tracks[0]
    assert track.chaser and rec.kind[-1] == NodeKind.CHASER
    assert rec.position.shape[1] - 1 not in track.net_nodes
    for j in range(rec.time.size):
        arrow = thrust_arrow(track, j)
        if rec.time[j] < series["time"][0]:
            assert arrow is None
            continue
        thrust = series["thrust"][np.searchsorted(series["time"], rec.time[j])]
        start = rec.position[j, -1] + 0.5 * CHASER_SIZE * direction
        end = start + THRUST_LENGTH * thrust / series["thrust"].max() * direction
        np.testing.assert_allclose(arrow[0], [start, end], rtol=0, atol=1e-12)
    with viser_server() as server:
        viewer = LiveViewer(server, replay, [0.1])
        layer = viewer.layers[0]
        assert "chaser" in viewer.controls and viewer.tow_panel is not None
        for k in (0, replay.time.size - 1):
            viewer.goto(k)
            np.testing.assert_allclose(layer.chaser.position, rec.position[k, -1], rtol=1e-6)
            assert layer.thrust.visible == (rec.time[k] >= series["time"][0])
        viewer._show("chaser", False)
        assert not layer.chaser.visible and not layer.thrust.visible
        viewer._show("chaser", True)
        assert layer.chaser.visible and layer.thrust.visible


def test_tether_coloured_on_its_own_tension_scale(viewer_tow, runs):
    # reference: the documented scales, the 99th percentile of the positive tensions of each
    # kind of line over the recordings (bulletnet.analysis.metrics.element_tension,
    # element_kinds; the tow's net is slack, the capture's has no tether), and the colour law
    # of thread_colours on the tether's scale
    from bulletnet.model.net import ElementKind
    from bulletnet.viewer.server import LiveViewer

    recs = [bn.open_recording(p) for p in (viewer_tow, runs["capture"])]
    replay = load_replay([viewer_tow, runs["capture"]])
    for name, kinds in (("net", [ElementKind.NET, ElementKind.CORNER]),
                        ("tether", [ElementKind.TETHER])):
        taut = np.concatenate([
            t[t > 0] for t in (bn.metrics.element_tension(rec)[:, np.isin(
                bn.metrics.element_kinds(rec), kinds)] for rec in recs)])
        assert replay.tension_scale[name] == pytest.approx(np.percentile(taut, 99), rel=1e-12)
    assert set(replay.tension_scale) == {"net", "tether"}
    tension = bn.metrics.element_tension(recs[0])
    scale = np.where(bn.metrics.element_kinds(recs[0]) == ElementKind.TETHER,
                     replay.tension_scale["tether"], replay.tension_scale["net"])
    with viser_server() as server:
        viewer = LiveViewer(server, replay, [0.1])
        np.testing.assert_array_equal(viewer.layers[0].force_scale["tension"], scale)
        np.testing.assert_array_equal(viewer.layers[0].threads.colors,
                                      thread_colours(tension[0], scale, replay.tracks[0].colour))


def test_failed_threads_drawn_as_red_stubs_and_counted(viewer_broken):
    # reference: the recorded failure times (/threads/failure_time, -1: intact): a thread has
    # failed at a frame after the step it failed in, the frame's time over its failure time;
    # at the end the count is bulletnet.analysis.metrics.breakage's
    from bulletnet.viewer.replay import FAILED, STUB, segment_colours, segment_points

    with h5py.File(viewer_broken) as f:
        failure_time, position = f["threads/failure_time"][()], f["nodes/position"][()]
        time, pairs = f["time"][()], f["threads/pairs"][()]
    replay = load_replay([viewer_broken])
    track, panel = replay.tracks[0], Panel(replay, [0.1])
    breaks = np.flatnonzero(failure_time >= 0)
    assert breaks.size and replay.has_breakage
    np.testing.assert_array_equal(track.breakable, breaks)
    intact = np.setdiff1d(np.arange(pairs.shape[0]), breaks)
    for j in range(time.size):
        failed = (failure_time >= 0) & (time[j] > failure_time)
        points = segment_points(track, j)
        colours = segment_colours(track, j, track.tension[j], replay.tension_scale["net"])
        a, b = position[j, pairs[:, 0]], position[j, pairs[:, 1]]
        np.testing.assert_array_equal(points[intact], np.stack([a, b], axis=1)[intact])
        # the threads that fail: two halves while intact, two stubs once failed
        length = np.where(failed[breaks], STUB, 0.5)[:, None]
        a, b = a[breaks], b[breaks]
        np.testing.assert_allclose(points[breaks], np.stack([a, a + length * (b - a)], axis=1),
                                   rtol=0, atol=1e-12)
        np.testing.assert_allclose(points[pairs.shape[0]:],
                                   np.stack([b, b + length * (a - b)], axis=1),
                                   rtol=0, atol=1e-12)
        red = np.all(colours[:, 0] == FAILED, axis=1)
        np.testing.assert_array_equal(red, np.concatenate([failed, failed[breaks]]))
        assert panel.updates(j)["failed-count"]["text"] == f"failed threads: {failed.sum()}"
    broken = bn.metrics.breakage(bn.open_recording(viewer_broken))["broken_threads"]
    assert panel.updates(time.size - 1)["failed-count"]["text"] == f"failed threads: {broken}"


def test_html_export_of_a_tow_ships_the_tow_panel_first(viewer_tow, tmp_path):
    # reference: the panels' own frames (TowPanel.updates, Panel.updates) at every frame
    import json

    from bulletnet.viewer import export_html
    from bulletnet.viewer.panel import TowPanel

    replay = load_replay([viewer_tow])
    page = export_html(replay, tmp_path / "tow.html", [0.1]).read_text()
    data = json.loads(page.split("window.__BULLETNET__=", 1)[1].split(";</script>", 1)[0])
    assert [p["title"] for p in data["panels"]] == ["Tow", "Mouth"]
    for shipped, panel in zip(data["panels"], (TowPanel(replay), Panel(replay, [0.1])),
                              strict=True):
        assert shipped["svg"] == panel.svg(0)
        for k in range(replay.time.size):
            update = panel.updates(k)
            assert shipped["values"][k] == [update[i][a] for i, a in shipped["fields"]]

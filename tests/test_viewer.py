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

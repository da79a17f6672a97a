"""The user's journey end to end: the demo chain against ground truth, the commands' outputs and their errors."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest

from conftest import need
from facepuppet.cli import main
from facepuppet.errors import FacepuppetError
from gltf_validator import gltf_validator  # noqa: F401  (fixture)

ERROR_BAR = 0.5
#: Bound on the demo's error with the colour tracker on smaller, shorter videos (5 s, 256 px, seed 0; it measures
#: 0.40 with OpenCV 5.1: the margin is for other OpenCV builds' rounding, which the colour network's
#: deterministic fit keeps from moving its weights).
COLOUR_BOUND = 0.5


def test_demo_meets_the_error_bar(demo):
    assert demo.coverage > 0.95
    assert demo.error <= ERROR_BAR, f"relative vertex error {demo.error:.3f} > {ERROR_BAR}"
    scored = np.isfinite(demo.error_per_frame)
    assert scored.sum() > demo.frames // 3            # most of the performance shows an expression


def test_demo_writes_every_file(demo):
    from facepuppet.demo.run import FILES, MONKEY_FILES

    expected = set(FILES) - set(MONKEY_FILES) - ({"performer-profile.npz"} if demo.tracker != "color" else set())
    assert set(demo.files) == expected
    for name in expected:
        path = demo.files[name]
        assert path.is_file() and path.stat().st_size > 0, name
    assert not [p for p in demo.files["animation.glb"].parent.iterdir() if p.name.startswith(".")]


def test_demo_videos_open(demo):
    from facepuppet.io.frames import open_media

    for name in ("performance.mp4", "overlay.mp4", "preview.mp4"):
        with open_media(demo.files[name]) as src:
            frames = sum(1 for _ in src)
        assert frames == demo.frames, name
    with open_media(demo.files["preview.mp4"]) as src:
        assert src.frame_size[0] > src.frame_size[1]          # side by side


def test_demo_glbs_pass_the_validator(demo, gltf_validator):  # noqa: F811
    for name in ("animation.glb", "toy.glb"):
        gltf_validator.check(demo.files[name])


def test_demo_csv_header_and_rows(demo):
    with open(demo.files["animation.csv"], newline="") as f:
        rows = list(csv.reader(f))
    header = rows[0]
    assert header[:2] == ["Timecode", "BlendShapeCount"]
    assert "JawOpen" in header and "EyeBlinkLeft" in header and "HeadYaw" in header
    assert len(rows) - 1 == demo.frames
    assert all(len(r) == len(header) for r in rows[1:])


def test_demo_track_and_rig_reload(demo):
    from facepuppet.io.track import load_track
    from facepuppet.pipeline.rig import load_rig

    track = load_track(demo.files["track.npz"])
    rig = load_rig(demo.files["rig.npz"])
    from facepuppet.demo.run import TruthTracker

    assert track.n_frames == demo.frames
    assert track.backend == ("color" if demo.tracker == "color" else TruthTracker.name)
    assert tuple(rig.point_names) == tuple(track.point_names)


def test_demo_command_says_what_tracked(tmp_path, capsys):
    from facepuppet.demo.run import DEFAULT_TRACKER

    code = main(["demo", "-o", str(tmp_path / "d"), "--seconds", "5", "--no-preview", "--no-progress"])
    out = capsys.readouterr().out
    assert code == 0
    assert "relative vertex error against ground truth" in out
    assert DEFAULT_TRACKER == "color"                   # the demo analyses the images it renders
    assert "the colour tracker" in out and "TRUE" not in out and "px from the true ones" in out
    code = main(["demo", "-o", str(tmp_path / "t"), "--seconds", "5", "--no-preview", "--no-progress",
                 "--tracker", "truth"])
    out = capsys.readouterr().out                       # never pretend a tracker saw what it did not
    assert code == 0 and "TRUE image curves" in out and "with the TRUE curves as the track" in out
    assert (tmp_path / "d" / "animation.glb").is_file() and not (tmp_path / "d" / "preview.mp4").exists()


def test_demo_runs_with_the_colour_tracker(tmp_path):
    """The whole chain with the colour tracker on a smaller face and a quicker performance than the default.

    The default demo (the colour tracker, 320 px) meets the bar (:data:`ERROR_BAR`, test above); at 256 px with
    all 13 key expressions in 5 s this run measures about 0.40, with curves 0.6 px from the true ones. The bound
    catches the colour path getting worse on harder footage.
    """
    from facepuppet.demo.run import DemoConfig, run_demo
    from facepuppet.io.track import load_track

    result = run_demo(tmp_path, DemoConfig(seconds=5.0, size=256, tracker="color", preview=False, progress=False))
    assert result.tracker == "color" and result.coverage > 0.9
    assert result.error < COLOUR_BOUND, f"relative vertex error {result.error:.3f} >= {COLOUR_BOUND}"
    assert result.curve_error < 1.0
    assert load_track(result.files["track.npz"]).backend == "color"
    assert result.files["performer-profile.npz"].is_file()


def test_demo_runs_with_the_landmark_backend(tmp_path, face_landmarker):
    """The whole chain with the MediaPipe backend, the reference the colour tracker is measured against.

    With the calibration's head-motion span discounted by the mapping it meets the demo's bar: this run
    measured 0.38 (0.43 on each of the default 8 s, 320 px performances of seeds 0-2,
    ``benchmarks/eval_demo_color.py``; 0.48 and 0.58-0.69 without the span).
    """
    from facepuppet.demo.run import DemoConfig, run_demo
    from facepuppet.io.track import load_track

    result = run_demo(tmp_path, DemoConfig(seconds=5.0, size=256, tracker="mediapipe", preview=False,
                                           progress=False, model=str(face_landmarker)))
    assert result.tracker == "mediapipe" and result.coverage > 0.95
    assert result.error <= ERROR_BAR, f"relative vertex error {result.error:.3f} > {ERROR_BAR}"
    assert load_track(result.files["track.npz"]).backend == "mediapipe"
    assert "performer-profile.npz" not in result.files and not (tmp_path / "performer-profile.npz").exists()


def test_demo_refuses_a_missing_model(tmp_path, capsys):
    missing = tmp_path / "nowhere.task"
    assert main(["demo", "-o", str(tmp_path / "d"), "--tracker", "mediapipe", "--model", str(missing)]) == 1
    err = capsys.readouterr().err
    assert str(missing) in err and "not found" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "d").exists()
    assert main(["demo", "-o", str(tmp_path / "d"), "--model", str(missing)]) == 1
    assert "--model is for --tracker mediapipe" in capsys.readouterr().err
    assert not (tmp_path / "d").exists()


def test_demo_refuses_a_short_performance(tmp_path, capsys):
    assert main(["demo", "-o", str(tmp_path / "d"), "--seconds", "2"]) == 1
    err = capsys.readouterr().err
    assert "--seconds must be at least 4.6" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "d").exists()


# --- the commands and their errors ------------------------------------------------------------------------

def _video(path: Path, frames: int = 12, size: int = 64) -> Path:
    from facepuppet.export.preview import open_preview

    with open_preview(path, 30.0, (size, size)) as out:
        for k in range(frames):
            out.write(np.full((size, size, 3), 10 * k % 255, np.uint8))
    return path


@pytest.fixture(scope="module")
def toy_glb(tmp_path_factory):
    from facepuppet.demo.toy import toy_character
    from facepuppet.io.gltf import write_glb

    path = tmp_path_factory.mktemp("toy") / "toy.glb"
    write_glb(path, toy_character())
    return path


@pytest.mark.parametrize("marks, message", [
    ("0,neutral\n5,jawOpn\n", "line 2: the character has no key-model named 'jawOpn'"),
    ("0,neutral\n00:10.0,jawOpen\n", "line 2: 00:10.0 (jawOpen) is past the end of the video"),
    ("5,jawOpen\n", "no mark names the neutral face"),
])
def test_bad_marks_give_one_line_and_no_output(tmp_path, capsys, toy_glb, marks, message):
    video = _video(tmp_path / "clip.mp4")
    (tmp_path / "marks.csv").write_text(marks)
    out = tmp_path / "performer.npz"
    code = main(["calibrate", str(video), "--marks", str(tmp_path / "marks.csv"), "--character", str(toy_glb),
                 "-o", str(out)])
    err = capsys.readouterr().err
    assert code == 1
    assert message in err and len(err.strip().splitlines()) == 1
    assert not out.exists()


def test_unreadable_media_gives_one_line_and_no_output(tmp_path, capsys):
    bad = tmp_path / "broken.mp4"
    bad.write_bytes(b"\x00not a video at all" * 50)
    (tmp_path / "marks.csv").write_text("0,neutral\n3,jawOpen\n")
    out = tmp_path / "performer.npz"
    assert main(["calibrate", str(bad), "--marks", str(tmp_path / "marks.csv"), "-o", str(out)]) == 1
    err = capsys.readouterr().err
    assert "broken.mp4" in err and len(err.strip().splitlines()) == 1
    assert not out.exists()


@pytest.fixture(scope="module")
def demo_rig_and_track(demo):
    return demo.files["rig.npz"], demo.files["track.npz"]


def test_animate_from_a_track_writes_valid_glb_and_csv(tmp_path, demo_rig_and_track, gltf_validator):  # noqa: F811
    rig, track = demo_rig_and_track
    glb, table = tmp_path / "out.glb", tmp_path / "out.csv"
    code = main(["animate", "unused.mp4", "--rig", str(rig), "--track", str(track), "-o", str(glb), "--csv",
                 str(table), "--gain", "1.2", "--gain", "jawOpen=1.5", "--smoothing", "min_cutoff=1,beta=3",
                 "--no-progress"])
    assert code == 0
    gltf_validator.check(glb)
    with open(table, newline="") as f:
        assert sum(1 for _ in f) - 1 == np.load(track)["valid"].shape[0]


def test_rig_of_other_feature_points_is_refused(tmp_path, capsys, demo_rig_and_track):
    from facepuppet.pipeline.rig import Rig, load_rig, save_rig

    rig_path, track = demo_rig_and_track
    rig = load_rig(rig_path)
    other = tmp_path / "other-rig.npz"
    save_rig(other, Rig(rig.mapper, rig.character, rig.names, tuple(f"p{i}" for i in range(len(rig.point_names)))))
    glb = tmp_path / "out.glb"
    assert main(["animate", "unused.mp4", "--rig", str(other), "--track", str(track), "-o", str(glb)]) == 1
    err = capsys.readouterr().err
    assert "other-rig.npz: made for other feature points" in err and len(err.strip().splitlines()) == 1
    assert not glb.exists()


def test_animate_unreadable_media_leaves_no_output(tmp_path, capsys, demo_rig_and_track):
    rig, _ = demo_rig_and_track
    bad = tmp_path / "broken.mp4"
    bad.write_bytes(b"garbage" * 100)
    glb = tmp_path / "out.glb"
    assert main(["animate", str(bad), "--rig", str(rig), "-o", str(glb), "--no-progress"]) == 1
    assert "broken.mp4" in capsys.readouterr().err
    assert not glb.exists()


# --- real footage ---------------------------------------------------------------------------------------

def test_calibrate_with_marks_on_a_shared_clip(assets, face_landmarker, tmp_path, capsys):
    from facepuppet.io.performer import load_performer

    clip = assets / "video" / "performer_a.mp4"
    need(clip.is_file(), f"{clip} is missing")
    marks = tmp_path / "marks.csv"
    marks.write_text("# when,name\n0.3s,neutral\n00:04.0,jawOpen\n200,mouthSmile\n")
    out = tmp_path / "performer.npz"
    code = main(["calibrate", str(clip), "--marks", str(marks), "--backend", "mediapipe", "--model",
                 str(face_landmarker), "-o", str(out), "--no-progress"])
    assert code == 0, capsys.readouterr().err
    perf = load_performer(out)
    assert perf.names == ("jawOpen", "mouthSmile")
    assert perf.examples.shape[1:] == perf.neutral.shape and perf.neutral.shape[1] == 3
    assert np.isfinite(perf.examples).all()


def test_interactive_calibration_with_a_video_for_camera(assets, face_landmarker):
    from facepuppet.demo.toy import toy_character
    from facepuppet.io.character import Character
    from facepuppet.pipeline.examples import ExamplesConfig, from_camera
    from facepuppet.pipeline.tracking import TrackerOptions

    clip = assets / "video" / "performer_a.mp4"
    need(clip.is_file(), f"{clip} is missing")
    toy = toy_character()
    two = Character(toy.neutral, toy.targets[:2], toy.names[:2], toy.faces, "toy2")
    presses = {5: ord(" "), 60: ord(" "), 120: 13}
    shown = []

    def keys(k, picture):
        shown.append(picture.shape)
        return presses.get(k, -1)

    cfg = ExamplesConfig(tracker=TrackerOptions(backend="mediapipe", model=str(face_landmarker), progress=False))
    result = from_camera(f"camera:{clip}", two, config=cfg, keys=keys)
    assert result.names == two.names
    assert result.frames["neutral"][0] >= 5 and result.frames[two.names[1]][0] >= 120
    assert shown and shown[0][1] > shown[0][0]                # camera frame beside the key-model's picture

    with pytest.raises(FacepuppetError, match="cancelled"):
        from_camera(f"camera:{clip}", two, config=cfg, keys=lambda k, p: ord("q") if k == 3 else -1)
    with pytest.raises(FacepuppetError, match="stopped before"):
        from_camera(f"camera:{clip}", two, config=cfg, keys=lambda k, p: -1)

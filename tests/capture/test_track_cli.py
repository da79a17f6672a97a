"""`facepuppet track` through the CLI entry point."""

import cv2
import numpy as np

from facepuppet.cli import main
from facepuppet.io.track import load_track


def test_mediapipe_track_of_a_real_clip(assets, face_landmarker, tmp_path):
    out, preview = tmp_path / "t.npz", tmp_path / "o.mp4"
    code = main(["track", str(assets / "video" / "performer_c.mp4"), "-o", str(out), "--backend", "mediapipe",
                 "--model", str(face_landmarker), "--max-frames", "30", "--preview", str(preview),
                 "--no-progress"])
    assert code == 0
    track = load_track(out)
    assert track.n_frames == 30 and track.valid.all() and track.backend == "mediapipe"
    assert track.extras["blendshapes"].shape == (30, 52)
    assert preview.is_file() and cv2.VideoCapture(str(preview)).get(cv2.CAP_PROP_FRAME_COUNT) == 30


def test_corrupt_file_gives_one_line_and_no_output(tmp_path, capsys):
    bad = tmp_path / "bad.mp4"
    bad.write_bytes(b"not a video at all" * 10)
    out = tmp_path / "t.npz"
    assert main(["track", str(bad), "-o", str(out), "--backend", "mediapipe", "--no-progress"]) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "bad.mp4" in err
    assert list(tmp_path.iterdir()) == [bad]


def test_face_free_video_gives_no_output(face_landmarker, tmp_path, capsys):
    blank = tmp_path / "blank.mp4"
    w = cv2.VideoWriter(str(blank), cv2.VideoWriter_fourcc(*"mp4v"), 30.0, (160, 120))
    for _ in range(5):
        w.write(np.full((120, 160, 3), 128, np.uint8))
    w.release()
    out, preview = tmp_path / "t.npz", tmp_path / "o.mp4"
    code = main(["track", str(blank), "-o", str(out), "--backend", "mediapipe", "--model", str(face_landmarker),
                 "--preview", str(preview), "--no-progress"])
    assert code == 1 and "no face" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["blank.mp4"]

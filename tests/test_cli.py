import pytest

from facepuppet import __version__
from facepuppet.cli import main


def test_version(capsys):
    with pytest.raises(SystemExit) as e:
        main(["--version"])
    assert e.value.code == 0
    assert __version__ in capsys.readouterr().out


def test_no_command_prints_help_and_fails(capsys):
    assert main([]) == 2
    assert "usage" in capsys.readouterr().out


def test_unknown_command_is_a_usage_error(capsys):
    with pytest.raises(SystemExit) as e:
        main(["frobnicate"])
    assert e.value.code == 2


def _calibrate_args(argv):
    from facepuppet.cli import build_parser

    return build_parser().parse_args(["calibrate", *argv])


def test_calibrate_help_names_the_key_expressions_and_hides_the_old_option(capsys):
    with pytest.raises(SystemExit):
        main(["--help"])
    assert "capture the performer's key expressions" in capsys.readouterr().out
    with pytest.raises(SystemExit):
        main(["calibrate", "--help"])
    out = capsys.readouterr().out
    assert "--train-profile" in out and "--make-profile" not in out


@pytest.mark.parametrize("option", ["--train-profile", "--make-profile"])
def test_make_profile_is_an_alias_of_train_profile(option):
    args = _calibrate_args(["clip.mp4", "--auto", option, "p.npz", "-o", "e.npz"])
    assert args.train_profile == "p.npz"


@pytest.mark.parametrize("argv, message", [
    (["camera:0", "-o", "{out}"], "camera:0 needs --character"),                # MEDIA camera:N captures live
    (["--camera", "1", "-o", "{out}"], "camera:1 needs --character"),          # as --camera N does
    (["camera:0", "--auto", "-o", "{out}"], "need a recorded video, not a camera"),
    (["clip.mp4", "-o", "{out}"], "--marks MARKS.csv, --auto, or a camera"),
    (["camera:0", "--train-profile", "p.npz", "-o", "{out}"], "--train-profile needs MEDIA, a recorded clip"),
])
def test_calibrate_says_what_is_wrong_in_one_line(tmp_path, capsys, argv, message):
    out = tmp_path / "e.npz"
    assert main(["calibrate", *(a.format(out=out) for a in argv)]) == 1
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1
    assert not out.exists()

"""The rig file and `facepuppet rig`: pairing by name, save/load round trip, clear errors.

The file format is tested with a stand-in mapper that records what it was fitted on (so these tests check the
rig code, not the mapping); the tests marked ``real_mapper`` run the package's ExpressionMapper end to end.
"""

from __future__ import annotations

import numpy as np
import pytest

import facepuppet.mapping
from facepuppet.cli import main
from facepuppet.errors import FacepuppetError
from facepuppet.io.character import Character, save_character
from facepuppet.io.performer import Performer, save_performer
from facepuppet.pipeline.rig import RIG_FORMAT, RIG_VERSION, Rig, fit_rig, load_rig, pair_by_name, save_rig


class StandIn:
    """Records fit's arguments; weights() is the least-squares blend of the examples (exact at examples)."""

    def __init__(self, arrays):
        self.a = arrays

    @property
    def method(self):
        return str(self.a["method"])

    @classmethod
    def fit(cls, source_base, source_examples, target_base, target_examples, names=None, method="default"):
        return cls({"source_base": np.asarray(source_base), "source_examples": np.asarray(source_examples),
                    "target_examples": np.asarray(target_examples), "names": np.asarray(names or ()),
                    "method": np.asarray(method)})

    def to_arrays(self):
        return dict(self.a)

    @classmethod
    def from_arrays(cls, d):
        if "source_examples" not in d:
            raise ValueError("mapper arrays incomplete")
        return cls(dict(d))

    def weights(self, points):
        d = (np.asarray(self.a["source_examples"]) - self.a["source_base"]).reshape(len(self.a["names"]), -1)
        return np.linalg.lstsq(d.T, (np.asarray(points) - self.a["source_base"]).reshape(-1), rcond=None)[0]


@pytest.fixture
def stand_in(monkeypatch):
    monkeypatch.setattr(facepuppet.mapping, "ExpressionMapper", StandIn, raising=False)
    return StandIn


def make_pair(rng, perf_names=("smile", "blink", "frown"), char_names=("blink", "smile", "jawOpen")):
    p, v = 6, 12
    s_base = rng.normal(size=(p, 3))
    performer = Performer(s_base, s_base[None] + rng.normal(size=(len(perf_names), p, 3)) * 0.1,
                          tuple(perf_names), tuple(f"pt{i}" for i in range(p)))
    t_base = rng.normal(size=(v, 3))
    character = Character(t_base, t_base[None] + rng.normal(size=(len(char_names), v, 3)) * 0.1,
                          tuple(char_names), np.array([[0, 1, 2]]), "toy")
    return performer, character


def test_pair_by_name_is_exact_and_keeps_performer_order():
    p = pair_by_name(("smile", "Blink", "frown", "jawOpen"), ("jawOpen", "blink", "smile", "sneer"))
    assert p.names == ("smile", "jawOpen")
    assert p.only_performer == ("Blink", "frown") and p.only_character == ("blink", "sneer")


def test_fit_rig_pairs_examples_with_key_models(rng, stand_in):
    performer, character = make_pair(rng)
    rig, pairing = fit_rig(performer, character, method="paper")
    assert rig.names == ("smile", "blink") and pairing.only_performer == ("frown",)
    assert pairing.only_character == ("jawOpen",)
    a = rig.mapper.a
    np.testing.assert_array_equal(a["source_examples"], performer.examples[[0, 1]])
    np.testing.assert_array_equal(a["target_examples"], character.targets[[1, 0]])
    assert tuple(a["names"]) == ("smile", "blink") and str(a["method"]) == "paper"
    np.testing.assert_array_equal(rig.target_indices, [1, 0])
    np.testing.assert_array_equal(rig.character_weights(np.array([[0.25, 0.5]])), [[0.5, 0.25, 0.0]])
    with pytest.raises(ValueError, match="end in 2 values"):
        rig.character_weights(np.zeros(3))


def test_no_pair_is_an_error(rng, stand_in):
    performer, character = make_pair(rng, char_names=("Smile", "BLINK"))
    with pytest.raises(FacepuppetError, match="no key expression has a key-model of the same name"):
        fit_rig(performer, character)


def test_round_trip(tmp_path, rng, stand_in):
    performer, character = make_pair(rng)
    rig, _ = fit_rig(performer, character)
    save_rig(tmp_path / "rig.npz", rig)
    back = load_rig(tmp_path / "rig.npz")
    assert back.names == rig.names and back.point_names == performer.point_names
    assert back.character.names == character.names and back.character.name == "toy"
    np.testing.assert_array_equal(back.character.targets, character.targets)
    np.testing.assert_array_equal(back.character.faces, character.faces)
    for key, value in rig.mapper.a.items():
        np.testing.assert_array_equal(back.mapper.a[key], value)
    with np.load(tmp_path / "rig.npz", allow_pickle=False) as raw:
        assert str(raw["format"]) == RIG_FORMAT and int(raw["version"]) == RIG_VERSION


def _rewrite(src, dst, drop=(), **changes):
    with np.load(src, allow_pickle=False) as raw:
        arrays = {k: raw[k] for k in raw.files if k not in drop}
    arrays.update(changes)
    np.savez(dst, **arrays)
    return dst


def test_bad_rig_files(tmp_path, rng, stand_in):
    performer, character = make_pair(rng)
    good = tmp_path / "rig.npz"
    save_rig(good, fit_rig(performer, character)[0])
    with pytest.raises(FacepuppetError, match="no such file"):
        load_rig(tmp_path / "missing.npz")
    data = good.read_bytes()
    (tmp_path / "cut.npz").write_bytes(data[: len(data) * 2 // 3])
    with pytest.raises(FacepuppetError, match="cut.npz"):
        load_rig(tmp_path / "cut.npz")
    with pytest.raises(FacepuppetError, match="not a facepuppet rig file"):
        load_rig(_rewrite(good, tmp_path / "other.npz", format=np.asarray("facepuppet-performer")))
    with pytest.raises(FacepuppetError, match="version 7 is newer"):
        load_rig(_rewrite(good, tmp_path / "future.npz", version=np.asarray(7)))
    with pytest.raises(FacepuppetError, match="lacks character.targets"):
        load_rig(_rewrite(good, tmp_path / "part.npz", drop=("character.targets",)))
    with pytest.raises(FacepuppetError, match="invalid rig file.*mapper arrays incomplete"):
        load_rig(_rewrite(good, tmp_path / "mapper.npz", drop=("mapper.source_examples",)))
    with pytest.raises(FacepuppetError, match="invalid rig file.*not among the character"):
        load_rig(_rewrite(good, tmp_path / "names.npz", names=np.array(["smile", "frown"])))


def test_rig_rejects_unknown_or_repeated_names(rng):
    _, character = make_pair(rng)
    with pytest.raises(ValueError, match="not among"):
        Rig(None, character, ("nose",))
    with pytest.raises(ValueError, match="unique"):
        Rig(None, character, ("blink", "blink"))


# ------------------------------------------------------------------------------------------ the command

def write_inputs(tmp_path, rng, **names):
    performer, character = make_pair(rng, **names)
    save_performer(tmp_path / "examples.npz", performer)
    save_character(tmp_path / "toy.glb", character)
    return performer, character


def test_command_reports_unpaired_names_and_writes_the_rig(tmp_path, rng, stand_in, capsys):
    performer, character = write_inputs(tmp_path, rng)
    code = main(["rig", "--performer", str(tmp_path / "examples.npz"), "--character", str(tmp_path / "toy.glb"),
                 "-o", str(tmp_path / "rig.npz"), "--method", "paper"])
    out, err = capsys.readouterr()
    assert code == 0
    assert "key expressions with no key-model of that name: frown" in err
    assert "key-models with no key expression of that name: jawOpen" in err
    assert "2 key expressions paired" in out and "method paper" in out
    rig = load_rig(tmp_path / "rig.npz")
    assert rig.names == ("smile", "blink") and rig.character.names == character.names


def test_command_errors_are_one_line_and_leave_no_file(tmp_path, rng, stand_in, capsys):
    write_inputs(tmp_path, rng, char_names=("a", "b"))
    out = tmp_path / "rig.npz"
    code = main(["rig", "--performer", str(tmp_path / "examples.npz"), "--character", str(tmp_path / "toy.glb"),
                 "-o", str(out)])
    err = capsys.readouterr().err
    assert code == 1 and "no key expression has a key-model" in err and len(err.strip().splitlines()) == 1
    code = main(["rig", "--performer", str(tmp_path / "nope.npz"), "--character", str(tmp_path / "toy.glb"),
                 "-o", str(out)])
    assert code == 1 and "nope.npz: no such file" in capsys.readouterr().err
    code = main(["rig", "--performer", str(tmp_path / "examples.npz"), "--character", str(tmp_path / "x.glb"),
                 "-o", str(out)])
    assert code == 1 and "x.glb" in capsys.readouterr().err
    assert not out.exists() and not [p for p in tmp_path.iterdir() if p.name.startswith(".rig")]


# ------------------------------------------------------------------------- with the package's mapper

def _real_mapper():
    try:
        from facepuppet.mapping import ExpressionMapper
    except ImportError:
        ExpressionMapper = None
    if ExpressionMapper is None or not hasattr(ExpressionMapper, "from_arrays"):
        pytest.skip("facepuppet.mapping.ExpressionMapper (with to_arrays/from_arrays) is not there yet")
    return ExpressionMapper


@pytest.mark.parametrize("method", [None, "paper"])
def test_real_mapper_end_to_end(tmp_path, rng, capsys, method):
    _real_mapper()
    performer, character = write_inputs(tmp_path, rng)
    extra = [] if method is None else ["--method", method]
    assert main(["rig", "--performer", str(tmp_path / "examples.npz"), "--character",
                 str(tmp_path / "toy.glb"), "-o", str(tmp_path / "rig.npz"), *extra]) == 0
    rig = load_rig(tmp_path / "rig.npz")
    from facepuppet.mapping import DEFAULT_METHOD

    assert rig.mapper.method == (method or DEFAULT_METHOD)
    assert f"method {method or DEFAULT_METHOD};" in capsys.readouterr().out   # the fitted method, by name
    # each paired example maps to its own key-model, the neutral to the neutral
    for i, name in enumerate(rig.names):
        w = rig.mapper.weights(performer.examples[performer.names.index(name)])
        np.testing.assert_allclose(w, np.eye(len(rig.names))[i], atol=1e-6)
    np.testing.assert_allclose(rig.mapper.weights(performer.neutral), 0, atol=1e-6)
    # the loaded mapper is the fitted one
    fitted, _ = fit_rig(performer, rig.character, method=method)
    points = performer.neutral + rng.normal(size=(4,) + performer.neutral.shape) * 0.05
    np.testing.assert_allclose(rig.mapper.weights(points), fitted.mapper.weights(points), atol=1e-12)
    np.testing.assert_allclose(rig.mapper.synthesize(np.array([0.5, 0.25])), fitted.mapper.synthesize(
        np.array([0.5, 0.25])), atol=1e-12)


def test_real_mapper_diagnoses_twin_examples_in_one_line(tmp_path, rng, capsys):
    _real_mapper()
    performer, character = make_pair(rng, perf_names=("smile", "blink"), char_names=("smile", "blink"))
    twins = Performer(performer.neutral, np.stack([performer.examples[0]] * 2), performer.names)
    save_performer(tmp_path / "examples.npz", twins)
    save_character(tmp_path / "toy.glb", character)
    code = main(["rig", "--performer", str(tmp_path / "examples.npz"), "--character", str(tmp_path / "toy.glb"),
                 "-o", str(tmp_path / "rig.npz")])
    err = capsys.readouterr().err
    assert code == 1 and len(err.strip().splitlines()) == 1
    assert "smile" in err and "blink" in err
    assert not (tmp_path / "rig.npz").exists()


def test_real_mapper_on_ict_identities(tmp_path, ict):
    """Performer = ICT identity A's 68 landmarks, character = identity B: examples map to key-models."""
    _real_mapper()
    rng = np.random.default_rng(7)
    keys = [0, 10, 11, 26, 45, 46]  # browDown_L, eyeBlink_L/R, jawOpen, mouthSmile_L/R
    names = tuple(str(ict["expr_names"][k]) for k in keys)
    ids = ict["id_deltas"][:20]
    a = ict["neutral"] + np.tensordot(rng.normal(size=20), ids, 1)
    b = ict["neutral"] + np.tensordot(rng.normal(size=20), ids, 1)
    lm = ict["landmarks68"]
    performer = Performer(a[lm], np.stack([(a + ict["expr_deltas"][k])[lm] for k in keys]), names)
    character = Character(b, np.stack([b + ict["expr_deltas"][k] for k in keys]), names, ict["faces"], "b")
    save_performer(tmp_path / "a.npz", performer)
    save_character(tmp_path / "b.glb", character)
    assert main(["rig", "--performer", str(tmp_path / "a.npz"), "--character", str(tmp_path / "b.glb"),
                 "-o", str(tmp_path / "rig.npz")]) == 0
    rig = load_rig(tmp_path / "rig.npz")
    assert rig.names == names and len(rig.character.neutral) == 11248
    v = rig.mapper.synthesize(rig.mapper.weights(performer.examples[3]))
    np.testing.assert_allclose(v, rig.character.targets[3], atol=1e-4)


def test_command_reads_an_obj_folder_with_a_named_neutral(tmp_path, rng, stand_in, capsys):
    performer, character = make_pair(rng, char_names=("smile", "blink"))
    save_performer(tmp_path / "examples.npz", performer)
    save_character(tmp_path / "objs", character)
    (tmp_path / "objs" / "neutral.obj").rename(tmp_path / "objs" / "rest.obj")
    assert main(["rig", "--performer", str(tmp_path / "examples.npz"), "--character", str(tmp_path / "objs"),
                 "--neutral", "rest.obj", "-o", str(tmp_path / "rig.npz")]) == 0
    out, err = capsys.readouterr()
    assert "2 key expressions paired" in out and "frown" in err
    rig = load_rig(tmp_path / "rig.npz")
    np.testing.assert_array_equal(rig.character.neutral, character.neutral)

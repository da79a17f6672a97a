"""A regional rig through the pipeline: fit, file, the paper's guarantees, GLB = the regional formula, CSV, CLI.

The character is a flat grid whose key-models are compact bumps (exactly zero beyond their radius), so the
regions a key-model does not move are known; the performer's key expressions move disjoint sets of points.
"""

from __future__ import annotations

import csv

import numpy as np
import pygltflib
import pytest

from blender_python import blender  # noqa: F401  (fixture)
from facepuppet.capture.curves import POINT_NAMES
from facepuppet.cli import main
from facepuppet.errors import FacepuppetError
from facepuppet.io.character import Character, save_character
from facepuppet.io.performer import Performer, save_performer
from facepuppet.io.track import save_track
from facepuppet.pipeline.animate import AnimateConfig, animate, map_track
from facepuppet.pipeline.gain import parse_gain
from facepuppet.pipeline.rig import fit_rig, load_rig, save_rig
from facepuppet.pipeline.smoothing import SmoothingConfig
from synthetic_tracks import make_track
from three_loader import three_loader  # noqa: F401  (fixture)

#: (name, centre (x, y), displacement direction) of each key-model's bump.
KEYS = (("jawOpen", (0.0, -0.45), (0.0, -1.0, 0.2)), ("mouthSmile_L", (0.55, -0.2), (0.6, 0.6, 0.0)),
        ("mouthSmile_R", (-0.55, -0.2), (-0.6, 0.6, 0.0)), ("browInnerUp", (0.0, 0.45), (0.0, 1.0, 0.0)),
        ("eyeBlink_L", (0.6, 0.2), (0.0, -0.5, 0.3)))
RADIUS = 0.3
NO_SMOOTHING = SmoothingConfig(enabled=False)


def grid_character() -> Character:
    x, y = np.meshgrid(np.linspace(-1, 1, 25), np.linspace(-0.7, 0.7, 15))
    base = np.stack([x.ravel(), y.ravel(), np.zeros(x.size)], axis=1)
    targets = []
    for _, (cx, cy), direction in KEYS:
        r2 = ((base[:, :2] - (cx, cy)) ** 2).sum(1) / RADIUS**2
        bump = np.where(r2 < 1, (1 - r2) ** 2, 0.0)
        targets.append(base + 0.2 * bump[:, None] * np.array(direction))
    cols = 25
    corner = [r * cols + c for r in range(14) for c in range(24)]
    faces = np.array([tri for k in corner for tri in ([k, k + 1, k + cols], [k + 1, k + cols + 1, k + cols])])
    return Character(base, np.array(targets), tuple(k[0] for k in KEYS), faces, "grid")


def performer(rng, names=tuple(k[0] for k in KEYS)) -> Performer:
    """Key expressions ``names`` that each move their own disjoint share of the points."""
    p = len(POINT_NAMES)
    neutral = rng.normal(size=(p, 3))
    examples = np.repeat(neutral[None], len(names), axis=0)
    for i in range(len(names)):
        own = np.arange(p) % len(names) == i
        examples[i, own] += rng.normal(scale=0.5, size=(own.sum(), 3))
    return Performer(neutral, examples, tuple(names), tuple(POINT_NAMES))


@pytest.fixture
def regional(rng):
    perf, character = performer(rng), grid_character()
    rig, _ = fit_rig(perf, character, method="regional")
    return perf, character, rig


def formula(rig, w):
    """T_B + sum_k sum_i M_k (.) w_ik (T_i - T_B) for w (F, R, M), in numpy."""
    c = rig.character
    d = c.targets[rig.target_indices] - c.neutral[None]
    return c.neutral + np.einsum("kv,fki,ivc->fvc", rig.mapper.region_masks, w, d)


def frames(perf, rng, n=12):
    """Neutral, each key expression, then blends of them with a little noise."""
    d = perf.examples - perf.neutral[None]
    w = np.vstack([np.zeros(len(d)), np.eye(len(d)), rng.uniform(0, 1, size=(n, len(d)))])
    pts = perf.neutral + np.einsum("fm,mpc->fpc", w, d)
    pts[1 + len(d):] += rng.normal(scale=0.02, size=pts[1 + len(d):].shape)
    return pts


def test_regional_rig_keeps_the_papers_guarantees_through_its_file(tmp_path, rng, regional):
    perf, character, rig = regional
    assert rig.regional and rig.region_names[0] == "background" and len(rig.region_names) > 2
    save_rig(tmp_path / "rig.npz", rig)
    back = load_rig(tmp_path / "rig.npz")
    assert back.regional and back.region_names == rig.region_names
    assert back.channel_names == tuple(f"{r}/{n}" for r in rig.region_names for n in rig.names)
    pts = frames(perf, rng)
    w = back.mapper.weights(pts)
    np.testing.assert_array_equal(w, rig.mapper.weights(pts))
    m = len(KEYS)
    np.testing.assert_allclose(w[0], 0.0, atol=1e-12)                                  # neutral -> neutral
    np.testing.assert_allclose(back.mapper.synthesize(w[0]), character.neutral, atol=1e-12)
    for i in range(m):                                                                 # key expression -> its key-model
        np.testing.assert_allclose(back.mapper.synthesize(w[1 + i]), character.targets[i], atol=1e-9)
    support = back.mapper.region_support
    assert (~support).any()
    assert (w[:, ~support] == 0).all()               # a region a key-model does not move takes no weight from it
    masks = back.mapper.region_masks
    moved = np.linalg.norm(character.targets - character.neutral[None], axis=2)        # (M, V)
    for k, i in zip(*np.nonzero(~support), strict=True):
        assert (masks[k] * moved[i]).max() <= 1e-3 * moved[i].max()


def read_accessor(g, index):
    """A float32 accessor's values (count, width), sparse ones included (zeros where they store nothing)."""
    acc = g.accessors[index]
    width = {"SCALAR": 1, "VEC3": 3, "VEC4": 4}[acc.type]

    def view_at(view_index, offset, count, dtype, k):
        view = g.bufferViews[view_index]
        start = (view.byteOffset or 0) + (offset or 0)
        return np.frombuffer(g.binary_blob(), dtype, count * k, start).reshape(count, k)

    if acc.bufferView is None:
        out = np.zeros((acc.count, width), np.float32)
    else:
        out = view_at(acc.bufferView, acc.byteOffset, acc.count, np.float32, width).copy()
    if acc.sparse is not None:
        sp = acc.sparse
        rows = view_at(sp.indices.bufferView, sp.indices.byteOffset, sp.count, np.uint32, 1)[:, 0]
        out[rows] = view_at(sp.values.bufferView, sp.values.byteOffset, sp.count, np.float32, width)
    return out


def glb_vertices(path):
    """Per key frame, T_B + sum_j weight_j target_j computed from the GLB's own accessors; and target names."""
    g = pygltflib.GLTF2.load(str(path))
    (mesh,) = g.meshes
    (prim,) = mesh.primitives
    base = read_accessor(g, prim.attributes.POSITION).astype(float)
    targets = np.stack([read_accessor(g, t["POSITION"]) for t in prim.targets]).astype(float)
    (anim,) = g.animations
    weights = read_accessor(g, anim.samplers[0].output).reshape(-1, len(targets)).astype(float)
    return base + np.einsum("fj,jvc->fvc", weights, targets), weights, tuple(mesh.extras["targetNames"])


def test_animated_glb_and_csv_of_a_regional_rig(tmp_path, rng, regional):
    perf, character, rig = regional
    track = make_track(frames(perf, rng))
    cfg = AnimateConfig(smoothing=NO_SMOOTHING, head_rotation=False)
    anim = animate(None, rig, glb=tmp_path / "out.glb", csv=tmp_path / "out.csv", track=track, config=cfg)
    r, m = len(rig.region_names), len(KEYS)
    assert anim.names == rig.channel_names and anim.weights.shape == (track.n_frames, r * m)
    w = anim.weights.reshape(-1, r, m)
    np.testing.assert_allclose(w, rig.mapper.weights(track.points), atol=1e-12)
    verts, glb_w, names = glb_vertices(tmp_path / "out.glb")
    assert names == rig.channel_names
    np.testing.assert_allclose(glb_w, anim.weights, atol=1e-6)
    np.testing.assert_allclose(verts, formula(rig, w), atol=1e-5)
    np.testing.assert_allclose(verts[0], character.neutral, atol=1e-6)
    np.testing.assert_allclose(verts[1:1 + m], character.targets, atol=1e-5)
    with open(tmp_path / "out.csv", newline="") as fh:
        rows = list(csv.reader(fh))
    assert rows[0] == ["time", "valid", *rig.channel_names]
    np.testing.assert_allclose(np.array(rows[1:], dtype=float)[:, 2:], anim.weights, atol=1e-6)


def test_regional_glb_of_the_pipeline_plays_in_threejs(tmp_path, rng, regional, three_loader):  # noqa: F811
    perf, _, rig = regional
    track = make_track(frames(perf, rng))
    cfg = AnimateConfig(smoothing=NO_SMOOTHING, head_rotation=False)
    anim = animate(None, rig, glb=tmp_path / "out.glb", track=track, config=cfg)
    w = anim.weights.reshape(-1, len(rig.region_names), len(KEYS))
    out = three_loader.play(tmp_path / "out.glb", [float(np.float32(8 / track.fps))])
    (at8,) = out["samples"]
    np.testing.assert_allclose(at8["influences"], anim.weights[8], atol=1e-6)
    np.testing.assert_allclose(at8["positions"], formula(rig, w[8:9])[0], atol=1e-5)


def test_regional_glb_of_the_pipeline_plays_in_blender(tmp_path, rng, regional, blender):  # noqa: F811
    perf, _, rig = regional
    track = make_track(frames(perf, rng))
    cfg = AnimateConfig(smoothing=NO_SMOOTHING, head_rotation=False)
    anim = animate(None, rig, glb=tmp_path / "out.glb", track=track, config=cfg)
    w = anim.weights.reshape(-1, len(rig.region_names), len(KEYS))
    out = blender.load(tmp_path / "out.glb", int(round(track.fps)), [8])
    (mesh,) = out["meshes"]
    assert mesh["shape_keys"] == ["Basis", *rig.channel_names]
    (at8,) = out["samples"]
    z_up = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])  # glTF's (x, y, z) -> (x, -z, y)
    np.testing.assert_allclose(at8["positions"][mesh["name"]], formula(rig, w[8:9])[0] @ z_up.T, atol=1e-5)


def test_region_gain_on_a_regional_rig(rng, regional):
    perf, _, rig = regional
    track = make_track(frames(perf, rng))
    base = map_track(rig, track, AnimateConfig(smoothing=NO_SMOOTHING))
    out = map_track(rig, track, AnimateConfig(smoothing=NO_SMOOTHING, gain=parse_gain(["mouth=0.5"])))
    r, m = len(rig.region_names), len(KEYS)
    mouth = np.array([n.startswith("mouth") for n in rig.region_names])
    assert mouth.any()
    w0, w1 = base.weights.reshape(-1, r, m), out.weights.reshape(-1, r, m)
    np.testing.assert_allclose(w1[:, mouth], 0.5 * w0[:, mouth], atol=1e-12)
    np.testing.assert_allclose(w1[:, ~mouth], w0[:, ~mouth], atol=1e-12)
    with pytest.raises(ValueError, match="no key-model or region named nose"):
        map_track(rig, track, AnimateConfig(gain=parse_gain(["nose=2"])))


def test_rig_and_animate_regional_on_the_command_line(tmp_path, rng, capsys):
    perf = performer(rng)
    save_performer(tmp_path / "perf.npz", perf)
    save_character(tmp_path / "grid.glb", grid_character())
    assert main(["rig", "--performer", str(tmp_path / "perf.npz"), "--character", str(tmp_path / "grid.glb"),
                 "-o", str(tmp_path / "rig.npz"), "--method", "regional"]) == 0
    said = capsys.readouterr().out
    assert "method regional" in said and "regions: background" in said
    rig = load_rig(tmp_path / "rig.npz")
    save_track(tmp_path / "track.npz", make_track(frames(perf, rng)))
    assert main(["animate", str(tmp_path / "track.npz"), "--track", str(tmp_path / "track.npz"), "--rig",
                 str(tmp_path / "rig.npz"), "-o", str(tmp_path / "out.glb"), "--smoothing", "off",
                 "--no-head", "--gain", "brows=0.5"]) == 0
    r, m = len(rig.region_names), len(KEYS)
    assert f"{r * m} channels ({r} regions x {m} key-models)" in capsys.readouterr().out
    # the character's own scene (a .glb): its M targets, driven to zero, then the R·M split ones
    verts, glb_w, names = glb_vertices(tmp_path / "out.glb")
    assert names == (*(k[0] for k in KEYS), *rig.channel_names)
    np.testing.assert_allclose(glb_w[:, :m], 0.0)
    w = glb_w[:, m:].reshape(-1, r, m)
    np.testing.assert_allclose(verts, formula(rig, w), atol=1e-5)
    assert main(["animate", str(tmp_path / "track.npz"), "--track", str(tmp_path / "track.npz"), "--rig",
                 str(tmp_path / "rig.npz"), "-o", str(tmp_path / "x.glb"), "--gain", "nose=2"]) != 0
    assert "nose" in capsys.readouterr().err


def test_live_senders_refuse_a_regional_rig(regional):
    from facepuppet.live.session import run_live

    _, _, rig = regional
    with pytest.raises(FacepuppetError, match="regional rig"):
        run_live("unused.mp4", rig, senders=[object()])


def test_region_gain_on_a_global_rig_scales_the_key_models_mostly_in_it(rng):
    perf, character = performer(rng), grid_character()
    rig, _ = fit_rig(perf, character)                       # the default (global) mapping
    assert not rig.regional and rig.channel_names == rig.names
    track = make_track(frames(perf, rng))
    base = map_track(rig, track, AnimateConfig(smoothing=NO_SMOOTHING, gain=parse_gain(["0.8"])))
    out = map_track(rig, track, AnimateConfig(smoothing=NO_SMOOTHING,
                                              gain=parse_gain(["0.8", "mouth=0.5", "mouthSmile_L=0.5"])))
    g = np.array([0.8, 0.25, 0.5, 0.8, 0.8])   # smiles lie in the mouth regions; key x region gains multiply
    np.testing.assert_allclose(out.weights, np.clip(base.weights / 0.8 * g, 0, 1), atol=1e-12)
    with pytest.raises(ValueError, match="no key-model or region named nose"):
        map_track(rig, track, AnimateConfig(gain=parse_gain(["nose=2"])))


def test_region_gain_shares_and_ambiguous_names():
    from facepuppet.pipeline.gain import key_gain

    names, regions = ("jawOpen", "smile", "jaw"), ("background", "jaw", "mouth_L")
    shares = np.array([[0.1, 0.2, 0.5], [0.8, 0.3, 0.5], [0.1, 0.5, 0.0]])
    two = np.array([[0.1, 0.2], [0.8, 0.2], [0.1, 0.6]])
    np.testing.assert_allclose(key_gain(parse_gain(["mouth=2"]), names[:2], regions, two), [1, 2])
    np.testing.assert_allclose(key_gain(parse_gain(["jaws=0.5", "smile=3"]), names[:2], regions, two), [0.5, 3])
    with pytest.raises(ValueError, match="no key-model of the rig moves mostly in region mouth"):
        key_gain(parse_gain(["mouth_L=2"]), names, regions, shares)            # 0.5 is not more than half
    with pytest.raises(ValueError, match=r"--gain jaw=2: 'jaw' is both a key-model and a region"):
        key_gain(parse_gain(["jaw=2"]), names, regions, shares)
    np.testing.assert_allclose(key_gain(parse_gain(["3", "jawOpen=2"]), names, regions, shares), [2, 3, 3])


def test_regional_rig_of_a_scene_character_keeps_the_scene(tmp_path, rng):
    """A glTF character's own scene (skin, materials, other meshes) is kept with the split targets added; each
    mesh plays the regional formula (read back: T_B + Σ w δ over the file's targets at the animated weights)."""
    from facepuppet.io.gltf import read_gltf
    from facepuppet.io.scene import parse_glb
    from scene_characters import HEAD_DEFAULTS, skinned_character

    made = skinned_character(rng)
    (tmp_path / "c.glb").write_bytes(made["glb"])
    character = read_gltf(tmp_path / "c.glb")
    names = ("jawOpen", "eyeBlinkLeft", "mouthSmileLeft")
    perf = performer(rng, names)
    rig, _ = fit_rig(perf, character, method="regional")
    assert rig.regional
    save_rig(tmp_path / "rig.npz", rig)
    rig = load_rig(tmp_path / "rig.npz")
    track = make_track(frames(perf, rng))
    anim = animate(None, rig, glb=tmp_path / "out.glb", track=track,
                   config=AnimateConfig(smoothing=NO_SMOOTHING, head_rotation=False))
    doc_in, _ = parse_glb(made["glb"])
    doc_out, _ = parse_glb((tmp_path / "out.glb").read_bytes())
    for key in ("nodes", "skins", "materials", "images"):
        assert doc_out[key] == doc_in[key]
    back = read_gltf(tmp_path / "out.glb")
    assert set(rig.channel_names) <= set(back.names)
    r, m = len(rig.region_names), len(names)
    w = anim.weights.reshape(-1, r, m)
    d = character.deltas[[character.names.index(n) for n in names]]
    extra = HEAD_DEFAULTS[3] * character.deltas[character.names.index("extraShape")]
    for f in (0, len(w) // 2, len(w) - 1):
        weights = np.zeros(len(back.names))
        weights[back.names.index("extraShape")] = HEAD_DEFAULTS[3]
        for c, value in zip(rig.channel_names, anim.weights[f], strict=True):
            weights[back.names.index(c)] = value
        shown = back.neutral + np.tensordot(weights, back.deltas, axes=1)
        expected = character.neutral + extra + np.einsum("kv,ki,ivc->vc", rig.mapper.region_masks, w[f], d)
        np.testing.assert_allclose(shown, expected, atol=1e-5)

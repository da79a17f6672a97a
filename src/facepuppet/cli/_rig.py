"""`facepuppet rig`: pair a performer's key expressions with a character's key-models by name, fit, save."""

from __future__ import annotations

import argparse
import sys

#: The mapper's own names of its inputs, as the user knows them.
_WORDS = {"source_examples": "the key expressions", "source_base": "the neutral face",
          "target_examples": "the key-models", "target_base": "the neutral mesh", "target_deltas": "the key-models"}


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "rig", help="fit the rig: the mapping from the performer's key expressions to a character's key-models",
        description="Pair the performer's key expressions with the character's key-models of the same name "
                    "(exact, case-sensitive), fit the expression mapper on the pairs and save the rig.")
    p.add_argument("--performer", required=True, metavar="EXAMPLES.npz",
                   help="key expressions file (facepuppet calibrate)")
    p.add_argument("--character", required=True, metavar="CHARACTER",
                   help=".glb / .gltf / .vrm with morph targets, a folder of OBJ files (neutral + one per key-model), "
                        "or a built-in character by name: toy")
    p.add_argument("-o", "--output", required=True, metavar="RIG.npz", help="rig file to write")
    p.add_argument("--method", default=None,
                   help="mapping method by name (default: the most accurate; regional: weights per face region); "
                        "the one fitted is printed")
    p.add_argument("--neutral", default=None, metavar="NAME",
                   help="OBJ folder: the neutral OBJ's file name (default neutral.obj)")
    p.add_argument("--mesh", default=None, metavar="NAME", help="glTF: read only this mesh")
    p.set_defaults(run=run,
                   inputs=(("performer", "--performer"), ("character", "--character")),
                   outputs=(("output", "-o"),))


def run(args: argparse.Namespace) -> int:
    import numpy as np

    from facepuppet.demo.characters import load_character_arg
    from facepuppet.errors import FacepuppetError
    from facepuppet.io.performer import load_performer
    from facepuppet.pipeline.rig import fit_rig, save_rig

    performer = load_performer(args.performer)
    character = load_character_arg(args.character, neutral=args.neutral, mesh=args.mesh)
    moved = np.abs(performer.examples - performer.neutral[None]).reshape(len(performer.examples), -1).max(axis=1)
    if not (moved > 0).any():
        raise FacepuppetError(f"--performer {args.performer}: no key expression differs from the neutral face")
    try:
        rig, pairing = fit_rig(performer, character, method=args.method)
    except (FacepuppetError, ValueError) as e:
        text = str(e)
        for internal, told in _WORDS.items():
            text = text.replace(internal, told)
        raise FacepuppetError(f"--performer {args.performer} with --character {args.character}: cannot fit "
                              f"the rig ({text})") from e
    if pairing.only_performer:
        print(f"facepuppet rig: warning: key expressions with no key-model of that name: "
              f"{', '.join(pairing.only_performer)}", file=sys.stderr)
    if pairing.only_character:
        print(f"facepuppet rig: warning: key-models with no key expression of that name: "
              f"{', '.join(pairing.only_character)}", file=sys.stderr)
    save_rig(args.output, rig)
    v = len(character.neutral)
    print(f"rig: {len(pairing.names)} key expressions paired with key-models of {character.name!r} "
          f"({v} vertices, {len(character.names)} key-models); method {rig.mapper.method}"
          + (f" ({len(rig.region_names)} regions: {', '.join(rig.region_names)})" if rig.regional else "")
          + f"; wrote {args.output}")
    return 0

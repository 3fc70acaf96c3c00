"""``flexvox simulate`` and ``flexvox scenes``: scene-driven simulation into a recording."""

from __future__ import annotations

import json
import re
import warnings
from pathlib import Path
from typing import TYPE_CHECKING

from flexvox_app.cli.errors import EXIT_OK, CliError, arg_type, defer
from flexvox_core.tiles import parse_tile

if TYPE_CHECKING:  # the simulator is imported where it runs: parsing needs none of it
    from flexvox_core.simulate.scene_file import SceneSpec

_SIZE_RE = re.compile(r"^\s*(\d+)\s*[xX]\s*(\d+)\s*$")


def _size(text: str) -> tuple[int, int]:
    match = _SIZE_RE.match(text)
    if match is None or min(int(match.group(1)), int(match.group(2))) < 8:
        raise ValueError(f"--size must be HxW with H, W >= 8 (e.g. 120x160); got {text!r}")
    return int(match.group(1)), int(match.group(2))


def parse_effect_overrides(text: str, current: dict) -> dict:
    """Apply ``--effects`` overrides: comma-separated ``name``, ``name.param=value`` or ``none``.

    ``none`` removes every effect declared so far; ``name`` declares an effect with its
    defaults (or keeps its current parameters); ``name.param=value`` sets one parameter, once (a second setting of
    the same parameter is refused).
    """
    from flexvox_core.simulate.effects import EFFECTS

    table = {k: dict(v) for k, v in current.items()}
    given: dict[str, str] = {}  # name.param -> the item that set it, since the last `none`
    for item in (t.strip() for t in text.split(",")):
        if not item:
            continue
        if item == "none":
            table, given = {}, {}
            continue
        name, _, assignment = item.partition(".")
        if name not in EFFECTS:
            raise ValueError(f"unknown effect {name!r}; effects: {', '.join(EFFECTS)}")
        table.setdefault(name, {})
        if assignment:
            key, eq, value = assignment.partition("=")
            if not eq:
                raise ValueError(f"--effects item {item!r} must be name.param=value")
            if f"{name}.{key}" in given:  # the last had been taken without a word
                raise ValueError(f"--effects sets {name}.{key} twice ({given[f'{name}.{key}']} and {item}): give it "
                                 "once")
            given[f"{name}.{key}"] = item
            try:
                table[name][key] = float(value)
            except ValueError:
                raise ValueError(f"--effects {name}.{key} must be a number; got {value!r}") from None
    return table


def register(sub) -> None:
    """Add the ``simulate`` and ``scenes`` subcommands."""
    p = sub.add_parser("simulate", help="simulate what the rig's camera records of a scene, into a recording")

    def describe(p) -> None:  # names the scenes and the video formats: imported only when this command is used
        from flexvox_core.simulate.scenes import SCENES
        from flexvox_core.simulate.sources import SUFFIXES

        p.description = (
            "Simulate a scene into a Zarr recording. SCENE is a scene file (.toml), a built-in "
            f"scene name ({', '.join(SCENES)}), or a video file ({', '.join(SUFFIXES)}). Only the "
            "effects the scene declares (or --effects adds) are simulated; with none, the frames "
            "are the ideal forward model exactly."
        )

    defer(p, describe)
    p.add_argument("scene", metavar="SCENE", help="scene file, built-in scene name, or video file")
    p.add_argument("-o", "--output", type=Path, required=True, metavar="REC.zarr", help="recording to write")
    code = p.add_mutually_exclusive_group()
    code.add_argument("--tile", type=arg_type(parse_tile), metavar="MxN",
                      help="tile of a designed code (overrides the scene's tile; refused where a scene file states "
                           "its own [code] order; default 4x4)")
    code.add_argument("--code", type=Path, metavar="CODE.json",
                      help="a code written by `flexvox design -o` (identity or multiplexed) instead of a designed "
                           "one (refused where a scene file states its own [code] order)")
    p.add_argument("--effects", metavar="SPEC",
                   help="effect overrides, comma-separated: NAME, NAME.PARAM=VALUE, or none "
                        "(e.g. none,photon_noise,read_noise.sigma=2); see `flexvox scenes`")
    p.add_argument("--frames", type=int, metavar="F", help="camera frames to simulate")
    p.add_argument("--size", type=arg_type(_size), metavar="HxW", help="size of a built-in scene")
    p.add_argument("--seed", type=int, metavar="S", help="random seed (scene texture and effect noise)")
    p.add_argument("--white", type=float, metavar="COUNTS",
                   help="a video file of integer counts: the count that stands for white (4095 for a 12-bit "
                        "camera; default the type's largest, 255 or 65535)")
    p.add_argument("--overwrite", action="store_true",
                   help="replace an existing recording (never the scene's own file, nor a recording being written; "
                        "the old one stays until the new one is complete)")
    p.set_defaults(func=run_simulate)

    q = sub.add_parser("scenes", help="list the built-in scenes and the effects with their parameters",
                       description="List the built-in scenes and every effect with its parameters, units and ranges.")
    q.add_argument("--json", action="store_true", help="print one JSON object")
    q.set_defaults(func=run_scenes)


def _spec_from_argument(text: str) -> SceneSpec:
    from flexvox_core.simulate.scene_file import SceneSpec, load_scene
    from flexvox_core.simulate.scenes import SCENES
    from flexvox_core.simulate.sources import SUFFIXES

    path = Path(text)
    if path.suffix.lower() == ".toml":
        return load_scene(path)
    if text in SCENES:
        return SceneSpec(builtin=text, name=text)
    if path.suffix.lower() in SUFFIXES:
        return SceneSpec(builtin=None, file=path, frames=None, name=path.stem)
    raise ValueError(
        f"SCENE {text!r} is neither a scene file (.toml), a built-in scene ({', '.join(SCENES)}), "
        f"nor a video file ({', '.join(SUFFIXES)})"
    )


def _use_code_file(spec, path: Path) -> None:
    """``spec`` takes the code of ``path`` (what ``flexvox design -o`` writes): an identity code's order, or a
    multiplexed code's tile and placement (refused, in the file's words, when it is neither)."""
    from flexvox_core.code_file import load_shutter_code
    from flexvox_core.codes import order_from_code
    from flexvox_core.multiplex import MultiplexedCode

    code = load_shutter_code(path)
    if isinstance(code, MultiplexedCode):
        spec.tile, spec.order, spec.multiplexed = tuple(code.tile), None, True
        spec.placement = code.placement.tolist()
    else:
        spec.tile, spec.order, spec.multiplexed = tuple(code.shape[:2]), order_from_code(code).tolist(), False


def run_simulate(args) -> int:
    """Carry out ``flexvox simulate``."""
    from flexvox_core.intensity import CountsWarning
    from flexvox_core.output_files import CLI_OVERWRITE_HINT, check_output
    from flexvox_core.recording import RecordingError, write_simulation
    from flexvox_core.simulate.effects import parse_effects
    from flexvox_core.simulate.simulator import simulate
    from flexvox_core.simulate.sources import TrimWarning, load_video

    try:
        spec = _spec_from_argument(args.scene)
        inputs = [Path(args.scene) if Path(args.scene).exists() else None, getattr(spec, "file", None)]
        # before it runs
        check_output(args.output, overwrite=args.overwrite, inputs=[*inputs, args.code], kind="store",
                     hint=CLI_OVERWRITE_HINT)
        given = f"--tile {args.tile[0]}x{args.tile[1]}" if args.tile else f"--code {args.code}" if args.code else None
        if given and spec.order is not None:  # the file's own code would be replaced, without a word
            flag = given.split()[0]
            raise ValueError(f"{given} would replace the code {args.scene} states in [code] order (a "
                             f"{spec.tile[0]}x{spec.tile[1]} tile): drop {flag} to simulate the scene's code, or "
                             f"take [code] order out of the file")
        if args.tile:
            spec.tile, spec.order = args.tile, None
        if args.code:
            _use_code_file(spec, args.code)
        if args.size:
            if spec.file is not None:
                raise ValueError(f"--size sets the size of a built-in scene; {spec.file} is a video of its own size "
                                 "(crop or resize it before simulating)")
            spec.height, spec.width = args.size
        if args.frames is not None:
            if args.frames < 1:
                raise ValueError(f"--frames must be >= 1; got {args.frames}")
            spec.frames, spec.duration_s = args.frames, None
        if args.seed is not None:
            if args.seed < 0:
                raise ValueError(f"--seed must be >= 0; got {args.seed}")
            spec.seed = args.seed
        if args.effects:
            current = {e.name: e.as_dict() for e in spec.effects}
            spec.effects = parse_effects(parse_effect_overrides(args.effects, current))
        if args.white is not None:
            if spec.file is None:
                raise ValueError("--white is the count that stands for white in a video file of counts; a built-in "
                                 "scene has none")
            spec.white = args.white
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", TrimWarning)
            warnings.simplefilter("always", CountsWarning)
            video = load_video(spec.file, white=spec.white) if spec.file is not None else None
            result = simulate(spec, video=video)
        for w in caught:
            print(f"warning: {w.message}")
        write_simulation(args.output, result, overwrite=args.overwrite)
    except (ValueError, RecordingError) as exc:
        raise CliError(str(exc)) from None
    except OSError as exc:  # the write failed (disk full, a file-size limit): written beside, nothing replaced
        old = "the old recording is unchanged" if args.output.exists() else "nothing was written"
        raise CliError(f"cannot write {args.output}: {exc.strerror or exc}; {old}") from None
    F, H, W = result.frames.shape
    effects = ", ".join(result.effects) or "none (ideal forward model)"
    print(f"simulated {result.source}: {F} frames of {H}x{W}, tile {spec.tile[0]}x{spec.tile[1]} "
          f"(K = {result.K}), {result.ground_truth.shape[0]} sub-frames at {result.rate_hz * result.K:g} Hz")
    print(f"effects: {effects}; seed {result.seed}; frames stored as {result.frames.dtype}")
    if result.dropped.any():
        print(f"dropped frames: {int(result.dropped.sum())} of {F}")
    print(f"wrote {args.output}")
    return EXIT_OK


def run_scenes(args) -> int:
    """Carry out ``flexvox scenes``."""
    from flexvox_core.simulate.effects import EFFECTS
    from flexvox_core.simulate.scenes import SCENES

    payload = {
        "scenes": {s.name: s.description for s in SCENES.values()},
        "effects": {
            cls.name: {
                "stage": cls.stage,
                "description": cls.description,
                "params": {p.name: {"unit": p.unit, "default": p.default, "min": p.minimum, "max": p.maximum,
                                    "description": p.description} for p in cls.params},
            }
            for cls in EFFECTS.values()
        },
    }
    if args.json:
        print(json.dumps(payload))
        return EXIT_OK
    print("built-in scenes:")
    for name, desc in payload["scenes"].items():
        print(f"  {name:<9} {desc}")
    print("\neffects (declare in a scene file's [effects] table, or with --effects):")
    for name, e in payload["effects"].items():
        print(f"  {name:<20} [{e['stage']}] {e['description']}")
        for pname, p in e["params"].items():
            print(f"      {pname:<12} {p['default']:g} {p['unit']} ({p['min']:g} .. {p['max']:g}): {p['description']}")
    print("\nelectron-domain effects use [camera] electrons_per_unit (default 1000 e-: a white scene, one open slot)")
    return EXIT_OK

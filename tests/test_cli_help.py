"""``simenv COMMAND [KIND] --help`` and usage errors: each comes from the parser that runs
the command, names ``simenv ...`` and lists the options (with their defaults)."""

from __future__ import annotations

import pytest

from simenv.assets import WALK, asset_path
from simenv.cli import main as cli
from simenv.cli.common import MODEL_KINDS

#: Options (or words) each command's help must list, and a default it must state.
EXPECTED: dict[tuple[str, ...], tuple[str, ...]] = {
    ("info",): ("--json", "--write-joint-map", "--joint-map"),
    ("retarget",): ("--out", "--video", "--stride", "--max-frames"),
    ("render",): ("--out", "--max-frames", "--width", "--height"),
    ("score",): ("--no-physics", "--reference", "--source", "--jobs"),
    ("export",): ("--to", "--scenario", "--stride"),
    ("demo",): ("--out", "--check", "--stride"),
    ("train", "predictor"): ("--past", "--future", "--minutes", "--config", "(default: 25)"),
    ("train", "classifier"): ("--epochs", "--max-minutes", "--out",
                              "(default: out/gesture-classifier)"),
    ("train", "recogniser"): ("--forecasters", "--epochs", "(default: out/gesture-tcn)"),
    ("train", "interaction"): ("--model", "interformer", "--config", "--seed"),
    ("eval", "predictor"): ("NAME", "--data", "--json", "(default: predictor-25-25)"),
    ("eval", "classifier"): ("NAME", "--benchmark", "--neighbour", "--covariance",
                             "--lie-group", "--data", "gesture-classifier",
                             "(default: predictor-gesture-25-50)"),
    ("eval", "recogniser"): ("NAME", "--benchmark", "--neighbour", "--checkpoint"),
    ("eval", "interaction"): ("--model", "--no-physics", "--label"),
    ("rehearse",): ("--scenario", "--gesture", "interformer", "reactive-gan", "--seconds",
                    "--no-render", "--joint-map", "(default: labels)"),
}


def test_every_command_and_kind_is_covered() -> None:
    commands = set(cli.build_parser()._subparsers._group_actions[0].choices)
    assert {argv[0] for argv in EXPECTED} == commands
    for verb in ("train", "eval"):
        assert {argv[1] for argv in EXPECTED if argv[0] == verb} == set(MODEL_KINDS)


@pytest.mark.parametrize("argv", list(EXPECTED), ids=" ".join)
def test_help_names_the_command_and_lists_its_options(argv: tuple[str, ...], capsys) -> None:
    with pytest.raises(SystemExit) as exc:
        cli.main([*argv, "--help"])
    out = capsys.readouterr().out
    assert exc.value.code == 0
    assert out.startswith(f"usage: simenv {' '.join(argv)} ")
    for option in EXPECTED[argv]:
        assert option in out, f"simenv {' '.join(argv)} --help does not list {option}"


@pytest.mark.parametrize("argv", [
    ["info", str(asset_path(WALK))],
    ["train", "predictor"],
    ["eval", "predictor"],
    ["eval", "classifier"],
    ["rehearse", str(asset_path(WALK)), "--out", "unused"],
], ids=lambda argv: " ".join(argv[:2]).replace(str(asset_path(WALK)), "FILE"))
def test_an_unknown_option_prints_that_commands_usage(argv: list[str], capsys) -> None:
    with pytest.raises(SystemExit) as exc:
        cli.main([*argv, "--jsn"])
    err = capsys.readouterr().err
    command = " ".join(a for a in argv[:2] if not a.startswith(("/", "-")))
    assert exc.value.code == 2
    assert err.startswith(f"usage: simenv {command} ")
    assert f"simenv {command}: error: unrecognized arguments: --jsn" in err


def test_bad_values_name_the_option_the_user_gave(capsys, tmp_path) -> None:
    with pytest.raises(SystemExit):
        cli.main(["eval", "classifier", "--benchmark", "nosuch"])
    err = capsys.readouterr().err
    assert "argument --benchmark: invalid choice: 'nosuch'" in err and "--dataset" not in err
    with pytest.raises(SystemExit):  # the benchmark-only options say so without --benchmark
        cli.main(["eval", "classifier", "--neighbour", "dtw"])
    assert "--neighbour: only with --benchmark" in capsys.readouterr().err
    with pytest.raises(SystemExit):  # a room option given to a reaction generator
        cli.main(["rehearse", str(asset_path(WALK)), "--out", str(tmp_path), "--agent",
                  "interformer", "--gesture", "smell:0.2:1.0"])
    assert "--gesture: not used with --agent interformer" in capsys.readouterr().err
    assert not any(tmp_path.iterdir())

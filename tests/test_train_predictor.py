"""What ``simenv train/eval predictor`` show people: a training bar whose end is the end of
training (the CPU budget or the iterations, whichever comes first) and tables with their
header row."""

from __future__ import annotations

from pathlib import Path

import pytest
from tqdm import tqdm

from simenv.cli import main as cli
from simenv.learning import train_predictor as tp
from simenv.models.training import CpuBudget


def test_training_bar_ends_with_the_cpu_budget() -> None:
    budget = CpuBudget(minutes=1.0)
    budget.start -= 30.0  # as if 30 CPU seconds went into the iterations so far
    bar = tqdm(range(20000), disable=True)
    tp._fit_total(bar, 100, 20000, budget)
    # 100 iterations in ~30 of the 60 budgeted CPU seconds: training ends near 200.
    assert 180 <= bar.total <= 200
    before = bar.total
    tp._fit_total(bar, 105, 20000, budget)  # re-estimated every 10 iterations only
    assert bar.total == before
    long = CpuBudget(minutes=600.0)
    long.start -= 30.0
    tp._fit_total(bar, 100, 20000, long)  # the iterations end first
    assert bar.total == 20000
    unlimited = tqdm(range(500), disable=True)
    tp._fit_total(unlimited, 100, 500, CpuBudget(None))
    assert unlimited.total == 500


def test_eval_table_has_its_header(capsys, shared_data: Path, tmp_path: Path) -> None:
    clip = shared_data / "cmu" / "bvh" / "02_01.bvh"
    if not clip.is_file():
        pytest.skip(f"{clip} not found")
    assert cli.main(["eval", "predictor", "predictor-10-10", "--data", str(clip), "--out",
                     str(tmp_path)]) == 0
    lines = capsys.readouterr().out.splitlines()
    header = next(i for i, line in enumerate(lines) if "MPJPE [mm] at" in line)
    assert lines[header].split()[3:] == [w for h in (80, 160, 320, 400, 1000)
                                         for w in (str(h), "ms")]
    rows = {line.split()[0]: line.split()[1:] for line in lines[header + 1:]}
    assert set(rows) == {"model", "zero_velocity", "constant_velocity"}
    # predictor-10-10 predicts 400 ms at 25 fps: no 1000-ms column value.
    assert all(len(row) == 5 and row[-1] == "n/a" for row in rows.values())

"""Tests for simenv.learning.eval_interaction: the real reactions score zero error, the JSON
contract, the generated report and the physics summary of one window."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from simenv.core.errors import SimenvError
from simenv.data import interaction_data as idata
from simenv.data import interaction_metrics as im
from simenv.learning import eval_interaction as ev
from simenv.learning.interaction_features import default_feature_extractor

#: The shipped generators of the reaction kind, one row each of the module's evaluation.
REACTION_MODELS = ("interformer", "reactive-gan")


@pytest.fixture(scope="module")
def results(shared_data: Path) -> dict:
    """One kinematic evaluation of the baselines and the shipped reaction generators (one
    run: the baselines' rows do not depend on which generators sit next to them)."""
    shipped = set(ev.shipped_models())
    return ev.evaluate(shared_data, physics=False, progress=False,
                       models=[n for n in REACTION_MODELS if n in shipped])


def test_json_contract_and_reference_row(results):
    assert results["pairs"] == results["data"]["test_windows"] > 0
    generators = set(REACTION_MODELS) & set(ev.shipped_models())
    assert {"nearest_neighbour", "mirror", "copy", "zero_velocity", ev.REAL} | generators == \
        set(results["results"])
    real = results["results"][ev.REAL]
    for key in ("AFD", "E_r_mm", "JPD_mm", "FVD", "FID", "lag_error_s"):
        assert real[key] == pytest.approx(0.0, abs=1e-9), key
    zero = results["results"]["zero_velocity"]
    assert zero["E_b_mm"] == pytest.approx(0.0, abs=1e-3)  # holds the reference frame
    assert zero["lag_defined_windows"] == 0 and zero["lag_error_s"] is None
    for name in ("nearest_neighbour", "mirror", "copy"):
        r = results["results"][name]
        assert r["AFD"] > 0 and r["E_r_mm"] > 0 and r["lag_defined_windows"] > 0
    # Recognition: the real test pairs are recognised far above chance (two trained
    # classes); a frozen reactor is much harder to recognise from the reactor alone.
    assert real["recognition_windows"] > 0 and real["recognition_acc"] > 0.8
    assert zero["recognition_reactor_acc"] < real["recognition_reactor_acc"]
    assert results["generation"] == {}
    assert set(results["data"]["test_recordings"]) == set(idata.DEFAULT_TEST_RECORDINGS)
    assert not set(results["data"]["train_recordings"]) & \
        set(results["data"]["test_recordings"])


def test_markdown_holds_the_computed_numbers(results, tmp_path):
    md = ev.render_markdown(results)
    afd = results["results"]["mirror"]["AFD"]
    assert f"| mirror | {afd:.3f} |" in md
    assert results["feature_extractor"] in md
    assert "shake_hands" in md
    png = ev.plot(results, tmp_path / "p.png")
    assert png.stat().st_size > 1000


@pytest.mark.usefixtures("quick_physics")  # the summary's fields, not its verdicts
def test_physics_summary_of_one_window(interaction_windows):
    windows = interaction_windows
    test = windows.subset(idata.split_by_recording(windows).test)
    index = ev.physics_windows(test)
    assert len(index) == len(idata.DEFAULT_TEST_RECORDINGS)
    d = im.joint_pair_distances(test.actor, test.reactor, [("right_hand", "right_hand")])
    first = np.flatnonzero(test.recording == test.recording[index[0]])
    assert d[index[0]].min() == pytest.approx(d[first].min())
    phys = ev.physics_of(test, index[1:2], {ev.REAL: test.reactor}, progress=False)
    row = phys[ev.REAL]
    assert row["windows"] == 1 and 0.0 <= row["reactor_plausible"] <= 1.0
    assert row["inter_penetration_max_mm"] is not None
    assert row["records"][0]["start_frame"] == int(test.start[index[1]])


def test_unknown_or_augmentation_models_are_refused(shared_data):
    for name in ("mirror", "interaction-augment"):
        with pytest.raises(SimenvError, match="not a reaction or interaction generator"):
            ev.evaluate(shared_data, physics=False, progress=False, models=[name])


@pytest.mark.parametrize("name", REACTION_MODELS)
def test_shipped_reaction_generators_are_rows_of_the_same_run(results, name):
    if name not in ev.shipped_models():
        pytest.skip(f"{name} is not shipped in assets/models")
    row = results["results"][name]
    assert row["AFD"] > 0 and 0.0 <= row["recognition_acc"] <= 1.0
    assert {"zero_velocity", "mirror", ev.REAL} <= set(results["results"])
    assert f"| {name} | {row['AFD']:.3f} |" in ev.render_markdown(results)


def test_interaction_generator_metrics_of_shipped_bigraphdiff(interaction_windows):
    from simenv.learning.interaction_recognition import InteractionRecognizer
    from simenv.models import load

    if "bigraphdiff" not in ev.shipped_models():
        pytest.skip("bigraphdiff is not shipped in assets/models")
    windows = interaction_windows
    split = idata.split_by_recording(windows)
    train, test = windows.subset(split.train), windows.subset(split.test)
    model = load("bigraphdiff")
    sub = test.subset(np.flatnonzero(np.isin(test.window_labels.astype(str),
                                             list(model.labels)))[::10])
    # A few sampling steps keep the test short; the evaluation uses the full schedule.
    actor, reactor = model.sample(list(sub.window_labels.astype(str)), seed=0, steps=10)
    extractor, _ = default_feature_extractor()
    rec = InteractionRecognizer(extractor).fit(train.actor, train.reactor, train.label)
    gen = ev.generation_metrics(sub, actor, reactor, extractor, rec)
    real = ev.generation_metrics(sub, sub.actor, sub.reactor, extractor, rec)
    assert gen["windows"] == len(sub) > 0
    for person in ("actor", "reactor"):
        assert real[person]["FVD"] == pytest.approx(0.0, abs=1e-6)
        assert gen[person]["FVD"] > 0 and gen[person]["E_b_mm"] > real[person]["E_b_mm"]
    assert 0.0 <= gen["recognition_acc"] <= 1.0 and real["recognition_acc"] > 0.5

"""``fricbench reproduce`` end to end with tiny networks: keys, files, report, CLI glue."""

from __future__ import annotations

import argparse
import dataclasses
import json

import pytest

import fricbench.bench.reproduce as rp
from fricbench.bench import reproduce_command as command
from fricbench.bench.reproduce import (
    ReproduceConfig,
    format_report,
    plot_figures,
    reproduce,
    write_json,
)

SMOKE = ReproduceConfig(
    predictors=("tf", "tf+lstm", "tf+stribeck"),
    predictor_params={"max_epochs": 1, "hidden_size": 4, "window": 300, "burn_in": 100},
    precomp_grid=((1, 1.0, 0), (1, 0.7, 3)),
    seeds=(0, 1, 2),
    verbose=False,
)


@pytest.fixture(scope="module")
def result():
    return reproduce(SMOKE)


def test_json_has_the_issue_keys(result, tmp_path) -> None:
    out = write_json(result, tmp_path / "out.json")
    data = json.loads(out.read_text())
    assert set(data["tf"]) == {"num", "den"}
    assert len(data["tf"]["den"]) == 4
    assert 0.5 < data["v_break_mm_s"] < 5.0
    assert data["train_seconds"] > 0
    for name in ("m_serial", "curve"):
        part = data[name]
        for key in ("tracking_max_um", "tf_max_um", "tf_lstm_max_um"):
            assert part[key] > 0
        assert set(part["precomp"]) == {"none_max_um", "tf_precomp_max_um",
                                        "tf_lstm_precomp_max_um"}
        assert part["precomp"]["none_max_um"] == pytest.approx(part["tracking_max_um"])
    assert data["cross_trajectory"]["evaluated_on"] == "curve"
    assert "curve" not in data["cross_trajectory"]["trained_on"]
    assert [p.name for p in tmp_path.iterdir()] == ["out.json"]  # atomic: no temp file left


def test_seed_spread_and_targets(result, tmp_path) -> None:
    ms, cu = result.trajectories["m_serial"], result.trajectories["curve"]
    assert [r.seed for r in result.seeds] == [0, 1, 2]
    first = result.seeds[0]  # the run the tables report
    assert first.ratio == {"m_serial": ms.ratio("tf+lstm"), "curve": cu.ratio("tf+lstm")}
    assert len({r.max_um["m_serial"] for r in result.seeds}) == 3  # each seed its own network
    sp = result.seed_spread()
    for key, s in sp.items():
        assert s["min"] <= s["median"] <= s["max"], key
    ratios = sorted(r.ratio["curve"] for r in result.seeds)
    assert sp["curve_ratio"] == {"median": ratios[1], "min": ratios[0], "max": ratios[2]}
    for r in result.seeds:
        assert r.precomp_cut["best"] == max(r.precomp_cut[k]
                                            for k in ("one_shot", "inverse", "tuned"))
    targets = result.targets()
    assert targets["m_serial_ratio"]["met"] == (sp["m_serial_ratio"]["median"] >= 5.0)
    assert targets["curve_ratio"]["met_by_seeds"] == sum(v >= 3.0 for v in ratios)
    data = json.loads(write_json(result, tmp_path / "o.json").read_text())
    assert data["seeds"]["seeds"] == [0, 1, 2] and data["seeds"]["targets"]["curve_ratio"]
    text = format_report(result)
    assert "judged on the median over the 3 seeds" in text and "per seed:" in text
    judged = text.split("judged on the median")[1].split("seed 0 alone")[0]
    assert judged.count("MISSED") == sum(not t["met"] for t in targets.values())


def test_a_seed_refitted_alone_matches_the_full_run(result) -> None:
    # the sweep's refit of seed 2 gives what a reproduction from seed 2 reports
    alone = reproduce(dataclasses.replace(SMOKE, seeds=(2,)))
    assert alone.seeds[0].max_um == result.seeds[2].max_um
    assert alone.seeds[0].precomp_cut == result.seeds[2].precomp_cut


def test_held_out_runs_differ_from_training(result) -> None:
    cfg = result.config
    assert cfg.train_noise_std != cfg.test_noise_std and cfg.train_seed != cfg.test_seed
    # the prediction error is measured against the held-out run's true position
    ms = result.trajectories["m_serial"]
    assert ms.max_um["tf"] > 1.0 and ms.tracking_max_um > ms.max_um["tf"] * 0.5


def test_figures_and_report(result, tmp_path) -> None:
    names = {p.name for p in plot_figures(result, tmp_path / "plots")}
    for n in range(11, 19):
        assert any(name.startswith(f"fig{n}_") for name in names), n
    assert "cross_curve_prediction_error.png" in names
    text = format_report(result)
    assert "TF+LSTM prediction error" in text and "paper" in text
    assert "3.5" in text and "8.0" in text  # the paper's TF+LSTM maxima sit beside ours
    assert "cross-trajectory" in text and "targets" in text


def test_cli_glue(result, tmp_path, monkeypatch, capsys) -> None:
    parser = argparse.ArgumentParser(prog="fricbench")
    sub = parser.add_subparsers(dest="command")
    command.add_parser(sub)
    args = parser.parse_args(["reproduce", "--json", str(tmp_path / "o.json"), "--plots",
                              str(tmp_path / "p"), "--max-epochs", "2", "--seeds", "3", "4",
                              "--quiet"])
    assert args.func is command.run
    seen = {}

    def fake(cfg: ReproduceConfig):
        seen["cfg"] = cfg
        return result

    monkeypatch.setattr(rp, "reproduce", fake)
    assert args.func(args) == 0
    assert seen["cfg"].predictor_params == {"max_epochs": 2} and not seen["cfg"].verbose
    assert seen["cfg"].seeds == (3, 4)
    out = capsys.readouterr().out
    assert "fricbench reproduce" in out and "wrote" in out
    assert json.loads((tmp_path / "o.json").read_text())["m_serial"]["tf_max_um"] > 0


def test_bad_arguments(capsys) -> None:
    assert command.main(["--predictors", "tf,nope", "--quiet"]) == 2
    assert "unknown predictor id 'nope'" in capsys.readouterr().err
    assert command.main(["--max-epochs", "0", "--quiet"]) == 2
    assert command.main(["--seeds", "1", "1", "--quiet"]) == 2
    assert "seeds=(1, 1): expected distinct seeds" in capsys.readouterr().err
    with pytest.raises(ValueError, match="seeds"):
        ReproduceConfig(seeds=())
    with pytest.raises(ValueError, match=r"seeds\[1\]"):
        ReproduceConfig(seeds=(0, -1))
    with pytest.raises(ValueError, match="test_seed"):
        ReproduceConfig(train_seed=3, test_seed=3)
    with pytest.raises(ValueError, match="precomp_grid"):
        ReproduceConfig(precomp_grid=())
    with pytest.raises(TypeError, match="ReproduceConfig"):
        reproduce({"verbose": False})  # type: ignore[arg-type]

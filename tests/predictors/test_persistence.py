"""Saved predictors: wrong version, wrong shapes, corrupt or foreign files give clear errors."""

from __future__ import annotations

import io
import json
import zipfile
from pathlib import Path

import pytest
import torch

from fricbench.predictors import Predictor, PredictorFileError
from fricbench.predictors.lstm import TFLSTMPredictor
from fricbench.predictors.tf import TFPredictor


@pytest.fixture(scope="module")
def saved(small_runs, tmp_path_factory, make_fast) -> dict[str, Path]:
    d = tmp_path_factory.mktemp("saved")
    out = {}
    for pid in ("tf", "tf+lstm"):
        p = d / f"{pid}.fbp"
        make_fast(pid).fit(small_runs).save(p)
        out[pid] = p
    return out


def _rewrite(src: Path, dst: Path, config: dict | None = None,
             state: dict | None = None) -> Path:
    with zipfile.ZipFile(src) as zf:
        cfg = json.loads(zf.read("config.json"))
        raw = zf.read("weights.pt")
    if config is not None:
        cfg.update(config)
    if state is not None:
        buf = io.BytesIO()
        torch.save(state, buf)
        raw = buf.getvalue()
    with zipfile.ZipFile(dst, "w") as zf:
        zf.writestr("config.json", json.dumps(cfg))
        zf.writestr("weights.pt", raw)
    return dst


def test_file_layout_is_config_plus_weights(saved) -> None:
    with zipfile.ZipFile(saved["tf+lstm"]) as zf:
        assert set(zf.namelist()) == {"config.json", "weights.pt"}
        cfg = json.loads(zf.read("config.json"))
        state = torch.load(io.BytesIO(zf.read("weights.pt")), weights_only=True)
    assert cfg["version"] == 1 and cfg["params"]["hidden_size"] == 8
    assert cfg["class"] == "fricbench.predictors.lstm:TFLSTMPredictor"
    assert all(isinstance(v, torch.Tensor) for v in state.values())


def test_wrong_version(saved, tmp_path) -> None:
    bad = _rewrite(saved["tf"], tmp_path / "v99.fbp", config={"version": 99})
    with pytest.raises(PredictorFileError, match=r"v99\.fbp.*version 99"):
        Predictor.load(bad)


def test_wrong_shape(saved, tmp_path) -> None:
    # the config says 9 hidden units, the weights have 8
    with zipfile.ZipFile(saved["tf+lstm"]) as zf:
        params = json.loads(zf.read("config.json"))["params"]
    bad = _rewrite(saved["tf+lstm"], tmp_path / "shape.fbp",
                   config={"params": {**params, "hidden_size": 9}})
    with pytest.raises(PredictorFileError, match=r"shape\.fbp.*net\.rnn\.weight_ih_l0.*shape"):
        Predictor.load(bad)
    # a TF of the wrong order
    with zipfile.ZipFile(saved["tf"]) as zf:
        state = torch.load(io.BytesIO(zf.read("weights.pt")), weights_only=True)
    state["tf_den"] = torch.zeros(7, dtype=torch.float64)
    bad = _rewrite(saved["tf"], tmp_path / "order.fbp", state=state)
    with pytest.raises(PredictorFileError, match=r"order\.fbp.*tf_den"):
        Predictor.load(bad)
    del state["tf_den"]
    bad = _rewrite(saved["tf"], tmp_path / "missing.fbp", state=state)
    with pytest.raises(PredictorFileError, match=r"missing\.fbp.*missing \['tf_den'\]"):
        Predictor.load(bad)


def test_corrupt_and_foreign_files(saved, tmp_path) -> None:
    junk = tmp_path / "junk.fbp"
    junk.write_bytes(b"\x00not a zip at all")
    with pytest.raises(PredictorFileError, match="junk.fbp.*not a fricbench predictor"):
        Predictor.load(junk)
    with pytest.raises(PredictorFileError, match="no such file"):
        Predictor.load(tmp_path / "absent.fbp")
    bad = _rewrite(saved["tf"], tmp_path / "cls.fbp", config={"class": "os:system"})
    with pytest.raises(PredictorFileError, match="not a Predictor"):
        Predictor.load(bad)
    bad = _rewrite(saved["tf"], tmp_path / "fmt.fbp", config={"format": "something-else"})
    with pytest.raises(PredictorFileError, match="not a fricbench predictor"):
        Predictor.load(bad)
    with zipfile.ZipFile(saved["tf"]) as zf:
        cfg = zf.read("config.json")
    trunc = tmp_path / "trunc.fbp"
    with zipfile.ZipFile(trunc, "w") as zf:
        zf.writestr("config.json", cfg)
        zf.writestr("weights.pt", b"garbage")
    with pytest.raises(PredictorFileError, match="trunc.fbp.*unreadable"):
        Predictor.load(trunc)
    bad = _rewrite(saved["tf"], tmp_path / "args.fbp", config={"params": {"n_poles": 0}})
    with pytest.raises(PredictorFileError, match="args.fbp.*constructor"):
        Predictor.load(bad)


def test_loading_through_the_wrong_class(saved) -> None:
    with pytest.raises(PredictorFileError, match="holds a TFPredictor, not a TFLSTMPredictor"):
        TFLSTMPredictor.load(saved["tf"])
    assert isinstance(TFPredictor.load(saved["tf"]), TFPredictor)


def test_save_is_atomic(saved, small_runs, tmp_path, make_fast) -> None:
    pred = Predictor.load(saved["tf"])
    target = tmp_path / "sub" / "model.fbp"
    pred.save(target)
    pred.save(target)  # overwrite in place
    assert sorted(p.name for p in target.parent.iterdir()) == ["model.fbp"]

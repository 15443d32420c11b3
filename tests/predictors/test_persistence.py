"""Saved predictors: wrong version, wrong shapes, corrupt or foreign files give clear errors."""

from __future__ import annotations

import io
import json
import os
import resource
import struct
import sys
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
    assert cfg["class"] == "tf+lstm"
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
    with pytest.raises(PredictorFileError, match="junk.fbp: not a valid zip archive"):
        Predictor.load(junk)
    with pytest.raises(PredictorFileError, match="no such file"):
        Predictor.load(tmp_path / "absent.fbp")
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


# -- hostile files (issue 14, items 1-3): no code runs, no size is trusted, every error names
# -- the file and the field -------------------------------------------------------------------

def _zip(dst: Path, members: dict[str, bytes],
         compression: int = zipfile.ZIP_DEFLATED) -> Path:
    with zipfile.ZipFile(dst, "w", compression=compression) as zf:
        for name, data in members.items():
            zf.writestr(name, data)
    return dst


def _members(src: Path) -> dict[str, bytes]:
    with zipfile.ZipFile(src) as zf:
        return {n: zf.read(n) for n in zf.namelist()}


def _forge_size(raw: bytes, suffix: str, size: int) -> bytes:
    """Rewrite the declared uncompressed size of the member ending in ``suffix``."""
    out = bytearray(raw)
    with zipfile.ZipFile(io.BytesIO(raw)) as zf:
        info = next(i for i in zf.infolist() if i.filename.endswith(suffix))
    assert out[info.header_offset:info.header_offset + 4] == b"PK\x03\x04"
    struct.pack_into("<I", out, info.header_offset + 22, size)  # local header
    cd = raw.index(b"PK\x01\x02")
    while True:  # the central directory record of this member
        n = struct.unpack_from("<H", out, cd + 28)[0]
        if out[cd + 46:cd + 46 + n].decode().endswith(suffix):
            break
        cd = raw.index(b"PK\x01\x02", cd + 4)
    struct.pack_into("<I", out, cd + 24, size)
    return bytes(out)


def test_class_field_never_imports_a_module(saved, tmp_path, monkeypatch) -> None:
    marker = tmp_path / "ran.txt"
    (tmp_path / "fb_evil_module.py").write_text(
        f"open({str(marker)!r}, 'w').write('code ran')\nX = 1\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.chdir(tmp_path)
    for i, value in enumerate(["fb_evil_module:X", "this:s", "os:system", ".relative:X",
                               "fricbench.predictors.tf:TFPredictor.__init__", 42, None]):
        bad = _rewrite(saved["tf"], tmp_path / f"cls{i}.fbp", config={"class": value})
        with pytest.raises(PredictorFileError,
                           match=rf"cls{i}\.fbp: config\.json class=.*registered predictor id"):
            Predictor.load(bad)
    assert not marker.exists()
    assert "fb_evil_module" not in sys.modules and "this" not in sys.modules


def test_class_field_is_a_registered_id(saved, tmp_path) -> None:
    with zipfile.ZipFile(saved["tf"]) as zf:
        assert json.loads(zf.read("config.json"))["class"] == "tf"
    # files written before ids were stored name the exact registered entry point: still load
    old = _rewrite(saved["tf+lstm"], tmp_path / "old.fbp",
                   config={"class": "fricbench.predictors.lstm:TFLSTMPredictor"})
    assert isinstance(Predictor.load(old), TFLSTMPredictor)


def test_registered_id_of_a_variant(small_runs, tmp_path, make_fast) -> None:
    pred = make_fast("tf+lstm-phys").fit(small_runs)
    pred.save(tmp_path / "phys.fbp")
    with zipfile.ZipFile(tmp_path / "phys.fbp") as zf:
        assert json.loads(zf.read("config.json"))["class"] == "tf+lstm-phys"
    assert Predictor.load(tmp_path / "phys.fbp").get_params() == pred.get_params()


def test_unregistered_class_cannot_be_saved(saved) -> None:
    class Unregistered(TFPredictor):
        pass

    pred = Unregistered()
    pred.__dict__.update(vars(Predictor.load(saved["tf"])))
    with pytest.raises(ValueError, match="Unregistered is not registered"):
        pred.save(saved["tf"].parent / "never.fbp")


def test_zip_bomb_refused_by_declared_size(saved, tmp_path) -> None:
    # weights.pt declares ~4 GiB: refused before anything is inflated
    raw = _forge_size(saved["tf"].read_bytes(), "weights.pt", 0xFFFFFFF0)
    bomb = tmp_path / "bomb.fbp"
    bomb.write_bytes(raw)
    with pytest.raises(PredictorFileError,
                       match=r"bomb\.fbp: members declare \d+ bytes uncompressed \(at "
                             r"'weights.pt'\); expected at most 268435456 bytes"):
        Predictor.load(bomb)


def test_member_inflating_past_its_declared_size_is_refused(tmp_path) -> None:
    raw = _zip(tmp_path / "src.zip", {"config.json": b"{}",
                                      "weights.pt": bytes(4 * 2**20)}).read_bytes()
    liar = tmp_path / "liar.fbp"
    liar.write_bytes(_forge_size(raw, "weights.pt", 1000))
    with pytest.raises(PredictorFileError, match=r"liar\.fbp.*weights\.pt"):
        Predictor.load(liar)


def test_oversized_and_special_files_refused(tmp_path) -> None:
    big = tmp_path / "big.fbp"
    with open(big, "wb") as fh:
        fh.truncate(256 * 2**20 + 1)  # sparse: no disk used
    with pytest.raises(PredictorFileError, match=r"big\.fbp: 268435457 bytes; expected at most"):
        Predictor.load(big)
    with pytest.raises(PredictorFileError, match="not a regular file"):
        Predictor.load(tmp_path)
    fifo = tmp_path / "fifo.fbp"
    os.mkfifo(fifo)
    with pytest.raises(PredictorFileError, match=r"fifo\.fbp: not a regular file"):
        Predictor.load(fifo)


def test_huge_zip_directory_refused(tmp_path) -> None:
    # zipfile builds an object per member before any can be checked: cap the directory
    many = tmp_path / "many.fbp"
    with zipfile.ZipFile(many, "w") as zf:
        for i in range(12_000):
            zf.writestr(f"{i:060d}", b"")
    with pytest.raises(PredictorFileError, match=r"many\.fbp: zip directory of \d+ bytes; "
                                                 "expected at most 1048576 bytes"):
        Predictor.load(many)


@pytest.mark.parametrize(("extra", "match"), [
    ({"evil.py": b"print(1)"}, r"unexpected \['evil.py'\]"),
    ({"../escape.txt": b"x"}, r"unexpected \['../escape.txt'\]"),
])
def test_unexpected_members_refused(saved, tmp_path, extra, match) -> None:
    bad = _zip(tmp_path / "extra.fbp", {**_members(saved["tf"]), **extra})
    with pytest.raises(PredictorFileError, match=rf"extra\.fbp: members .*{match}"):
        Predictor.load(bad)


def test_duplicate_and_bzip2_members_refused(saved, tmp_path) -> None:
    members = _members(saved["tf"])
    dup = tmp_path / "dup.fbp"
    with pytest.warns(UserWarning, match="Duplicate name"):
        _zip(dup, members)
        with zipfile.ZipFile(dup, "a") as zf:
            zf.writestr("weights.pt", b"second")
    with pytest.raises(PredictorFileError, match=r"dup\.fbp: members \['weights.pt'\] appear "
                                                 "more than once"):
        Predictor.load(dup)
    bz = _zip(tmp_path / "bz.fbp", members, compression=zipfile.ZIP_BZIP2)
    with pytest.raises(PredictorFileError, match=r"bz\.fbp: member 'config.json' uses "
                                                 "compression method 12"):
        Predictor.load(bz)


def test_deeply_nested_config(saved, tmp_path) -> None:
    depth = 200_000
    bad = _zip(tmp_path / "deep.fbp", {**_members(saved["tf"]),
                                       "config.json": b"[" * depth + b"]" * depth})
    with pytest.raises(PredictorFileError, match=r"deep\.fbp: config\.json: JSON nested too "
                                                 "deeply"):
        Predictor.load(bad)


def _state_of(path: Path) -> dict[str, torch.Tensor]:
    with zipfile.ZipFile(path) as zf:
        return torch.load(io.BytesIO(zf.read("weights.pt")), weights_only=True)


def test_sample_time_tensor_of_the_wrong_shape(saved, tmp_path) -> None:
    state = _state_of(saved["tf"])
    state["ts_"] = torch.tensor([1e-3, 1e-3], dtype=torch.float64)
    bad = _rewrite(saved["tf"], tmp_path / "ts2.fbp", state=state)
    with pytest.raises(PredictorFileError, match=r"ts2\.fbp: weights\.pt: tensor 'ts_' \(sample "
                                                 r"time\) has shape \(2,\); expected a scalar"):
        Predictor.load(bad)


@pytest.mark.parametrize(("pid", "name"), [("tf", "tf_num"), ("tf", "ts_"),
                                           ("tf+lstm", "net.rnn.weight_ih_l0")])
def test_integer_weights_refused(saved, tmp_path, pid, name) -> None:
    state = _state_of(saved[pid])
    state[name] = state[name].round().to(torch.int64)
    bad = _rewrite(saved[pid], tmp_path / "int.fbp", state=state)
    with pytest.raises(PredictorFileError, match=rf"int\.fbp: weights\.pt: tensor '{name}' has "
                                                 "dtype torch.int64; expected a floating dtype"):
        Predictor.load(bad)


@pytest.mark.parametrize(("value", "match"), [
    ({1: torch.zeros(1)}, "key 1 is a int; expected string keys"),
    ({"ts_": [1e-3]}, "'ts_' is a list; expected a tensor"),
    ({"ts_": torch.tensor(1e-3).to_sparse()}, "'ts_' has layout torch.sparse_coo"),
    ({"ts_": torch.zeros(1).expand(2**40)}, "tensors describe more than 268435456 bytes"),
    ([1, 2], "holds a list; expected a state_dict"),
])
def test_weights_that_are_not_a_dict_of_tensors(saved, tmp_path, value, match) -> None:
    bad = _rewrite(saved["tf"], tmp_path / "w.fbp", state=value)
    with pytest.raises(PredictorFileError, match=rf"w\.fbp: weights\.pt: .*{match}"):
        Predictor.load(bad)


def test_torch_records_bounded_by_declared_size(saved, tmp_path) -> None:
    # torch inflates a deflated record to its declared size: check it before torch does
    src = zipfile.ZipFile(io.BytesIO(_members(saved["tf"])["weights.pt"]))
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w", compression=zipfile.ZIP_DEFLATED) as zf:
        for info in src.infolist():
            zf.writestr(info.filename, src.read(info))
    inner = _forge_size(out.getvalue(), "data/0", 0xFFFFFFF0)
    bad = _zip(tmp_path / "inner.fbp", {**_members(saved["tf"]), "weights.pt": inner})
    with pytest.raises(PredictorFileError, match=r"inner\.fbp: weights\.pt: members declare "
                                                 r"\d+ bytes"):
        Predictor.load(bad)


def test_config_does_not_allocate_the_network_it_names(saved, tmp_path) -> None:
    # a 4-layer, 2048-unit LSTM is ~0.5 GB of weights; the check of a file's shapes must not
    # build it
    with zipfile.ZipFile(saved["tf+lstm"]) as zf:
        params = json.loads(zf.read("config.json"))["params"]
    bad = _rewrite(saved["tf+lstm"], tmp_path / "huge.fbp",
                   config={"params": {**params, "hidden_size": 2048, "num_layers": 4}})
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    with pytest.raises(PredictorFileError,
                       match=r"huge\.fbp: weights do not match TFLSTMPredictor"):
        Predictor.load(bad)
    grown_kib = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before
    assert grown_kib < 100 * 1024

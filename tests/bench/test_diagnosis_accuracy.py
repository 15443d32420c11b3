"""The diagnosis' accuracy benchmark: its sets are apart, its counts right, its table written.

The sweep itself (hundreds of diagnoses) is a benchmark command, not a test: here the sets, the
counting and one real run of the command on a single case are checked.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from fricbench.bench import diagnosis_accuracy as A


def test_heldout_set_is_fixed_distinct_and_apart_from_tuning() -> None:
    held = A.heldout_cases()
    assert held == A.heldout_cases()  # the same on every call and machine
    assert len(held) >= 100
    seeds = [s for _, s in held]
    assert len(set(seeds)) == len(seeds)
    tuning = {s for _, s in A.tuning_cases()}
    assert not tuning & set(seeds)
    assert min(seeds) >= A.HELDOUT_SEED_BASE
    kinds = [k for k, _ in held]
    # every kind of the simulator is held out about equally often
    counts = {k: kinds.count(k) for k in set(kinds)}
    assert max(counts.values()) - min(counts.values()) <= 1
    with pytest.raises(ValueError, match="n=0"):
        A.heldout_cases(0)


def _result(kind: str, present: str | None, named: tuple[str, ...], ok: bool,
            law: str = "cascade") -> A.CaseResult:
    return A.CaseResult(kind=kind, seed=1, present=present, named=named, ok=ok, failures=(),
                        law=law, log_rate="1kHz", effort="none", crashed=False, elapsed=1.0)


def test_summary_counts_found_missed_and_false_effects() -> None:
    friction = frozenset({"coulomb_friction", "stribeck_friction"})
    results = [
        _result("control", None, ("coulomb_friction",), True),
        _result("control", None, ("coulomb_friction", "backlash"), False, law="pid"),
        _result("cogging", "cogging", ("coulomb_friction", "cogging"), True),
        _result("backlash", "backlash", ("coulomb_friction", "cogging"), False),
    ]
    s = A.summarise(results, friction)
    assert (s.n, s.right) == (4, 2)
    assert (s.controls, s.controls_false) == (2, 1)
    assert s.present == {"cogging": 1, "backlash": 1}
    assert s.found["cogging"] == 1 and s.missed["backlash"] == 1
    assert s.false == {"backlash": 1, "cogging": 1}
    assert s.by_structure["law: pid"] == [0, 1]
    assert s.by_structure["law: cascade"] == [2, 3]


def test_command_writes_the_table_and_the_tuning_rows(tmp_path: Path,
                                                     monkeypatch: pytest.MonkeyPatch) -> None:
    # one tuning case, its diagnosis replaced by a known result (a real diagnosis of the second
    # simulator's runs is tested in tests/sysid; one costs minutes on a loaded machine)
    monkeypatch.setattr(A, "tuning_cases", lambda extra=True: [("control", 1)])
    monkeypatch.setattr(A, "diagnose_one", lambda kind, seed: _result(kind, None,
                                                                      ("coulomb_friction",), True))
    out = tmp_path / "diagnosis.md"
    assert A.main(["--set", "tuning", "--jobs", "1", "--out", str(out)]) == 0
    text = out.read_text()
    assert "## Tuning set: 1/1 right (100.0 %)" in text
    assert "control runs (friction only) with a false effect: 0/1" in text
    rows = (tmp_path / "diagnosis_tuning.csv").read_text().splitlines()
    assert rows[0].startswith("kind,seed") and rows[1].startswith("control,1,")
    assert oct(out.stat().st_mode & 0o777) != oct(0o600)


def test_command_refuses_bad_options(capsys: pytest.CaptureFixture) -> None:
    with pytest.raises(SystemExit) as exc:
        A.main(["--jobs", "0"])
    assert exc.value.code == 2
    assert "--jobs 0" in capsys.readouterr().err

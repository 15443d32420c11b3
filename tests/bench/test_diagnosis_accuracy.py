"""The diagnosis' accuracy benchmark: its sets are apart, its counts right, its table written.

The sweep itself (hundreds of diagnoses) is a benchmark command, not a test: here the sets, the
counting and one real run of the command on a single case are checked.
"""

from __future__ import annotations

from dataclasses import replace
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
    # the seeds studied outside the tuning set are no held-out case either
    import second_sim as S  # the benchmark put the simulators' folder on the path
    assert set(A.STUDIED_SEEDS) <= set(S.KINDS)
    assert not {(k, s) for k, ss in A.STUDIED_SEEDS.items() for s in ss} & set(held)
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
    # a simulator that does not say whether the drive clips gets no such row
    assert not any(k.startswith(("drive limit", "command delay")) for k in s.by_structure)


def test_summary_counts_runs_by_drive_limit_and_command_delay() -> None:
    friction = frozenset({"coulomb_friction"})
    results = [
        replace(_result("control", None, ("coulomb_friction",), True),
                drive_limit="reached", command_delay="none"),
        replace(_result("backlash", "backlash", ("coulomb_friction",), False),
                drive_limit="reached", command_delay="1-3 periods"),
        replace(_result("cogging", "cogging", ("coulomb_friction", "cogging"), True),
                drive_limit="none", command_delay="1-3 periods"),
    ]
    s = A.summarise(results, friction)
    assert s.by_structure["drive limit: reached"] == [1, 2]
    assert s.by_structure["drive limit: none"] == [1, 1]
    assert s.by_structure["command delay: none"] == [1, 1]
    assert s.by_structure["command delay: 1-3 periods"] == [1, 2]
    table = "\n".join(A._section("Held-out set", s))
    assert "| drive limit: reached | 1 | 2 | 50.0 |" in table


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


def test_third_heldout_set_is_its_own_fixed_and_apart_from_its_tuning() -> None:
    held = A.heldout_cases(sim="third")
    assert held == A.heldout_cases(sim="third")
    assert len(held) == A.THIRD_HELDOUT_RUNS >= 100
    seeds = [s for _, s in held]
    assert len(set(seeds)) == len(seeds) and min(seeds) >= A.HELDOUT_SEED_BASE
    assert not {s for _, s in A.tuning_cases(sim="third")} & set(seeds)
    assert seeds != [s for _, s in A.heldout_cases(len(held))]  # not the second's seeds
    kinds = [k for k, _ in held]
    counts = {k: kinds.count(k) for k in set(kinds)}
    assert len(counts) == 16 and max(counts.values()) == min(counts.values())
    # the first runs take the kinds in turn: 2 per kind is the first 32
    assert sorted({kinds[:32].count(k) for k in set(kinds)}) == [2]


def test_summary_counts_one_of_and_several_wanted_effects() -> None:
    friction = frozenset({"coulomb_friction", "force_offset", "asymmetric_friction"})
    results = [
        A.CaseResult(kind="vertical", seed=1, present="force_offset|asymmetric_friction",
                     named=("coulomb_friction", "asymmetric_friction"), ok=True, failures=(),
                     law="servo", log_rate="1kHz", effort="A", crashed=False, elapsed=1.0),
        A.CaseResult(kind="hum", seed=1, present=None, named=("cogging",), ok=False,
                     failures=("named absent cogging", "rms 1 -> 1 (x1.00), floor 0.1"),
                     law="servo", log_rate="1kHz", effort="none", crashed=False, elapsed=1.0),
    ]
    s = A.summarise(results, friction)
    assert s.found["force_offset|asymmetric_friction"] == 1 and not s.false.get("force_offset")
    assert (s.controls, s.controls_false) == (1, 1) and s.false == {"cogging": 1}
    assert s.by_kind == {"vertical": [1, 1], "hum": [0, 1]}
    assert s.why["hum"] == {"named absent cogging": 1, "rms": 1}
    table = "\n".join(A._section("Held-out set", s, per_kind=True))
    assert "| force_offset or asymmetric_friction | 1 | 1 | 0 | 0 |" in table
    assert "| hum | 0 | 1 | named absent cogging (1); rms (1) |" in table


def test_third_sim_section_keeps_the_second_sims_table(tmp_path: Path,
                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    out = tmp_path / "diagnosis.md"
    out.write_text("# Diagnosis accuracy on the second simulator\n\nsecond's figures\n")
    monkeypatch.setattr(A, "tuning_cases", lambda extra=True, sim="second": [("hum", 1)])
    monkeypatch.setattr(A, "diagnose_one_third", lambda kind, seed: A.CaseResult(
        kind=kind, seed=seed, present=None, named=("coulomb_friction",), ok=True, failures=(),
        law="servo", log_rate="1kHz", effort="A", crashed=False, elapsed=1.0))
    assert A.main(["--sim", "third", "--set", "tuning", "--jobs", "1", "--out", str(out)]) == 0
    text = out.read_text()
    assert text.startswith("# Diagnosis accuracy on the second simulator\n\nsecond's figures")
    assert A.THIRD_MARK in text and "# Diagnosis accuracy on the third simulator" in text
    assert "| hum | 1 | 1 |  |" in text
    assert (tmp_path / "diagnosis_third_tuning.csv").read_text().splitlines()[1].startswith(
        "hum,1,")
    # and the second simulator's rerun keeps the third's section
    monkeypatch.setattr(A, "diagnose_one", lambda kind, seed: _result(kind, None,
                                                                      ("coulomb_friction",), True))
    assert A.main(["--set", "tuning", "--jobs", "1", "--out", str(out)]) == 0
    again = out.read_text()
    assert "second's figures" not in again and "## Tuning set: 1/1 right" in again
    assert again.count(A.THIRD_MARK) == 1 and "| hum | 1 | 1 |  |" in again
    with pytest.raises(SystemExit) as exc:
        A.main(["--sim", "first"])
    assert exc.value.code == 2

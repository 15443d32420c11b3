"""The diagnosis' settings in one place (:mod:`fricbench.sysid.diagnose.settings`).

* no module of ``sysid/diagnose`` defines a numeric constant of its own (a few plumbing values
  aside, each named here with its reason): a tuned value is a field of
  :class:`DiagnoseSettings`;
* every field is documented and says whether its value was tuned (``metadata["tuned"]``);
* the count of tuned fields may only fall (a ratchet towards the issue's 15);
* the numbers written inline in each module (a bound, a start, a grid, a share, a unit) may
  only fall too: the module-level scan misses them, and that is where the thresholds of the
  case-by-case search also hid;
* a bad value is refused with the field, the value and what was expected.
"""

from __future__ import annotations

import ast
import dataclasses
import math
import re
from pathlib import Path

import pytest

import fricbench.sysid.diagnose as D
import fricbench.sysid.diagnose.settings as settings_module
from fricbench.sysid.diagnose.settings import DEFAULT_SETTINGS, DiagnoseSettings, defaults

# Module-level numeric values that are no setting: (module, name) -> why.
PLUMBING = {
    ("command.py", "EXIT_OK"): "an exit status of the command line",
    ("command.py", "EXIT_FAILED"): "an exit status of the command line",
    ("command.py", "EXIT_BAD_INPUT"): "an exit status of the command line",
    ("criterion.py", "UNIDENTIFIED"): "a sentinel: the variance factor of a direction the data "
                                      "do not determine, large enough to read as unknown",
    ("effects/friction_profile.py", "PROFILE_KNOTS"): "the candidate library's make-up: the "
                                                      "knot counts of the registered profiles, "
                                                      "each an effect of its own",
    ("models.py", "_DIVERGED"): "a sentinel: the residual given to the samples of a diverged "
                                "simulation, in noise-floor units",
}

# Tuned fields of DiagnoseSettings at the commit that gathered them (a ratchet: the count may
# only fall; the one-method issue's target is 15).
TUNED_AT_MOST = 18


def _numeric(node: ast.expr) -> bool:
    """A number written in the code: a literal, a signed one, or arithmetic of them."""
    if isinstance(node, ast.Constant):
        return isinstance(node.value, (int, float)) and not isinstance(node.value, bool)
    if isinstance(node, ast.UnaryOp):
        return _numeric(node.operand)
    if isinstance(node, ast.BinOp):
        return _numeric(node.left) and _numeric(node.right)
    return False


def _numeric_value(node: ast.expr) -> bool:
    """A number, or a tuple or list of numbers (None entries allowed beside them)."""
    if isinstance(node, (ast.Tuple, ast.List)):
        elts = [e for e in node.elts if not (isinstance(e, ast.Constant) and e.value is None)]
        return bool(elts) and all(_numeric(e) for e in elts)
    return _numeric(node)


def _module_assignments(body: list[ast.stmt]) -> list[tuple[str, ast.expr]]:
    """Module-level ``name = value`` (also under a module-level ``if`` or ``try``)."""
    out: list[tuple[str, ast.expr]] = []
    for node in body:
        if isinstance(node, ast.Assign):
            out += [(t.id, node.value) for t in node.targets if isinstance(t, ast.Name)]
        elif isinstance(node, ast.AnnAssign) and node.value is not None:
            if isinstance(node.target, ast.Name):
                out.append((node.target.id, node.value))
        elif isinstance(node, ast.If):
            out += _module_assignments(node.body) + _module_assignments(node.orelse)
        elif isinstance(node, ast.Try):
            out += _module_assignments(node.body) + _module_assignments(node.orelse)
            for handler in node.handlers:
                out += _module_assignments(handler.body)
    return out


def _numeric_constants() -> set[tuple[str, str]]:
    folder = Path(D.__file__).parent
    found = set()
    for path in sorted(folder.rglob("*.py")):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        for name, value in _module_assignments(tree.body):
            if _numeric_value(value):
                found.add((path.relative_to(folder).as_posix(), name))
    return found


def test_no_numeric_constant_in_the_diagnosis_outside_its_settings() -> None:
    new = _numeric_constants() - set(PLUMBING)
    assert not new, (f"module-level numeric constants in sysid/diagnose: {sorted(new)}; a "
                     "setting belongs in DiagnoseSettings (sysid/diagnose/settings.py), "
                     "documented with what it means and where its value came from")


def test_the_plumbing_allowed_still_exists() -> None:
    assert set(PLUMBING) <= _numeric_constants(), "an allowed constant is gone: drop its entry"


def test_the_scan_sees_a_constant() -> None:
    tree = ast.parse("A = 0.5\nB: float = -1e-3\nC = (1, 2 / 3)\nD = (None, 0.25)\n"
                     "if True:\n    E = 3\nF = 'x'\nG = (True,)\nH = len('ab')\n")
    found = {name for name, value in _module_assignments(tree.body) if _numeric_value(value)}
    assert found == {"A", "B", "C", "D", "E"}


# Numbers written inline in each module of sysid/diagnose (settings.py aside) at the commit that
# counted them: a ratchet. They are the effects' physical ranges and starts, grids, guards, unit
# conversions and report formats, and also thresholds in all but name (the loop's starting
# grids, the iteration budgets; prepared.py's four became fields). A new threshold, grid or
# start is a field of DiagnoseSettings; a count that falls is lowered here.
INLINE_NUMBERS_AT_MOST = {
    "baselines.py": 28, "command.py": 4, "controllers.py": 16, "coverage.py": 5,
    "criterion.py": 2, "diagnosis.py": 18, "effects/__init__.py": 3, "effects/asymmetric.py": 5,
    "effects/backlash.py": 10, "effects/base.py": 8, "effects/cogging.py": 22,
    "effects/cogging_harmonic.py": 4, "effects/compliance.py": 48, "effects/coulomb.py": 2,
    "effects/friction_profile.py": 10, "effects/offset.py": 1,
    "effects/position_dependent.py": 22, "effects/stribeck.py": 14, "effects/thermal.py": 10,
    "effects/thermal_strain.py": 4, "equation_error.py": 15, "leastsq.py": 2, "models.py": 35,
    "open_loop.py": 39, "parameters.py": 3, "prepared.py": 2, "report.py": 36, "search.py": 13,
    "signals.py": 49, "twin.py": 11, "verdict.py": 18,
}


def _inline_numbers(tree: ast.AST) -> int:
    """Numeric literals in ``tree`` but the structural ones (0, 1, 2, -1, a half) and the
    guards and sentinels (a float of at most 1e-6 or at least 1e6 in size: a division's floor,
    a tolerance, an "infinite" bound)."""
    count = 0
    for node in ast.walk(tree):
        if not (isinstance(node, ast.Constant) and isinstance(node.value, (int, float))
                and not isinstance(node.value, bool)):
            continue
        value = node.value
        if value in (0, 1, 2, -1, 0.5):
            continue
        if isinstance(value, float) and not 1e-6 < abs(value) < 1e6:
            continue
        count += 1
    return count


def _inline_counts() -> dict[str, int]:
    folder = Path(D.__file__).parent
    counts = {}
    for path in sorted(folder.rglob("*.py")):
        rel = path.relative_to(folder).as_posix()
        if rel == "settings.py":
            continue
        n = _inline_numbers(ast.parse(path.read_text(encoding="utf-8")))
        if n:
            counts[rel] = n
    return counts


def test_no_module_of_the_diagnosis_writes_more_numbers_inline_than_it_did() -> None:
    counts = _inline_counts()
    print(f"{sum(counts.values())} numbers written inline in sysid/diagnose")
    more = {k: (n, INLINE_NUMBERS_AT_MOST.get(k, 0)) for k, n in counts.items()
            if n > INLINE_NUMBERS_AT_MOST.get(k, 0)}
    assert not more, (f"numbers written inline (found, allowed): {more}; a threshold, a grid or "
                      "a start belongs in DiagnoseSettings (sysid/diagnose/settings.py), "
                      "documented with what it means and where its value came from")
    fewer = {k: (counts.get(k, 0), n) for k, n in INLINE_NUMBERS_AT_MOST.items()
             if counts.get(k, 0) < n}
    assert not fewer, (f"fewer numbers written inline (found, allowed): {fewer}; lower "
                       "INLINE_NUMBERS_AT_MOST to the counts found")


def test_the_inline_scan_sees_a_threshold_and_not_a_guard() -> None:
    code = ("def f(v, x):\n    if v < 0.02 * x and v > 1e-300:\n        return x[:3] * 2\n"
            "    return max(x, 1e9) - 1 + 0.5 * True\n")
    assert _inline_numbers(ast.parse(code)) == 2  # 0.02 and 3


def _documented() -> dict[str, str]:
    """The numpydoc ``Parameters`` entries of :class:`DiagnoseSettings`: name -> text."""
    doc = DiagnoseSettings.__doc__ or ""
    section = doc.split("Parameters\n    ----------\n", 1)[1]
    entries: dict[str, str] = {}
    name = None
    for line in section.splitlines():
        head = re.match(r"^    (\w+) : ", line)
        if head:
            name = head.group(1)
            entries[name] = ""
        elif name is not None and line.startswith("        "):
            entries[name] += " " + line.strip()
    return entries


def test_every_setting_is_documented_and_says_whether_it_was_tuned() -> None:
    entries = _documented()
    names = [f.name for f in dataclasses.fields(DiagnoseSettings)]
    assert list(entries) == names, "the docstring's entries must be the fields, in their order"
    for f in dataclasses.fields(DiagnoseSettings):
        assert isinstance(f.metadata.get("tuned"), bool), f"{f.name}: no metadata['tuned']"
        text = entries[f.name]
        assert len(text) > 40, f"{f.name}: say what it means, its unit and where it came from"
        if f.metadata["tuned"]:
            assert "Tuned" in text and "Not tuned" not in text, f"{f.name}: {text}"
        else:
            assert "Not tuned" in text, f"{f.name}: {text}"


def test_the_tuned_values_only_fall() -> None:
    tuned = sorted(f.name for f in dataclasses.fields(DiagnoseSettings) if f.metadata["tuned"])
    print(f"{len(tuned)} tuned settings (target 15): {', '.join(tuned)}")
    assert len(tuned) <= TUNED_AT_MOST, (f"{len(tuned)} tuned settings, more than the "
                                         f"{TUNED_AT_MOST} there were: {tuned}")
    assert f"Tuned values: {len(tuned)} today" in (settings_module.__doc__ or ""), (
        "the settings module's docstring must say how many tuned values there are")
    assert "target is at most 15" in (settings_module.__doc__ or "")


def test_the_defaults_are_valid_and_search_settings_is_the_same_class() -> None:
    from fricbench.sysid.diagnose import SearchSettings
    from fricbench.sysid.diagnose.search import SearchSettings as FromSearch

    assert SearchSettings is FromSearch is DiagnoseSettings
    assert DiagnoseSettings() == DEFAULT_SETTINGS
    assert SearchSettings(max_steps=3).max_steps == 3
    assert defaults() is settings_module.DEFAULT_SETTINGS
    assert DEFAULT_SETTINGS.heldout_gain == DEFAULT_SETTINGS.tolerance
    from fricbench.sysid.diagnose.search import effects_tried

    assert set(effects_tried(DEFAULT_SETTINGS)) >= {"coulomb_friction", "backlash"}
    assert effects_tried(DiagnoseSettings(candidates=("cogging",))) == ("cogging",)


def test_code_without_a_settings_object_reads_the_defaults_when_called(
        monkeypatch: pytest.MonkeyPatch) -> None:
    from fricbench.sysid.diagnose.prepared import substeps

    assert substeps(0.01) == 10  # 1 ms steps of a 10 ms sample
    monkeypatch.setattr(settings_module, "DEFAULT_SETTINGS",
                        dataclasses.replace(DEFAULT_SETTINGS, loop_ts=5e-3))
    assert substeps(0.01) == 2


@pytest.mark.parametrize("name", [f.name for f in dataclasses.fields(DiagnoseSettings)])
def test_a_nan_is_refused_by_every_setting(name: str) -> None:
    expect = next(f.metadata["expect"] for f in dataclasses.fields(DiagnoseSettings)
                  if f.name == name)
    with pytest.raises(ValueError) as err:
        DiagnoseSettings(**{name: math.nan})
    assert str(err.value) == f"{name}=nan: expected {expect}"


@pytest.mark.parametrize(("name", "value", "message"), [
    ("penalty", -1.0, "penalty=-1.0: expected a number >= 0"),
    ("folds", 1, "folds=1: expected an integer >= 2 (one block held out, at least one to fit "
                 "on)"),
    ("max_effects", -1, "max_effects=-1: expected an integer >= 0"),
    ("max_lag_share", 0.0, "max_lag_share=0.0: expected a share in (0, 0.5]"),
    ("max_steps", True, "max_steps=True: expected an integer >= 0"),
    ("n_confirm", 0, "n_confirm=0: expected an integer >= 1"),
    ("loop_box", 0.5, "loop_box=0.5: expected a number >= 1"),
    ("rest_speed_share", 1.0, "rest_speed_share=1.0: expected a share in (0, 1)"),
    ("one_block_worse", 0.5, "one_block_worse=0.5: expected a number >= 1"),
    ("compliance_zeta_min", 0.0, "compliance_zeta_min=0.0: expected a number > 0"),
    ("compliance_zeta_min", 0.5, "compliance_zeta_min=0.5: expected a damping ratio below "
                                 "0.382683, the highest the larger part allows "
                                 "(explained_share=0.5)"),
    ("delay_steps", (0, -1), "delay_steps=(0, -1): expected a non-empty tuple of integers >= 0"),
    ("limit_friction_grid", (), "limit_friction_grid=(): expected a non-empty tuple of numbers "
                               "> 0"),
    ("law_prefilters", (None, 2.0), "law_prefilters=(None, 2.0): expected a non-empty tuple of "
                                    "None (unfiltered) or shares of the Nyquist frequency in "
                                    "(0, 1]"),
    ("candidates", ("cogging", 1), "candidates=('cogging', 1): expected None (the whole "
                                   "library) or a tuple of effect names"),
    ("reach_quantile", 0.5, "reach_quantile=0.5: expected a quantile in (0.5, 1]"),
    ("explained_share", 1.0, "explained_share=1.0: expected a share in (0, 1)"),
])
def test_a_bad_value_names_the_field_the_value_and_what_was_expected(
        name: str, value: object, message: str) -> None:
    with pytest.raises(ValueError) as err:
        DiagnoseSettings(**{name: value})
    assert str(err.value) == message


def test_the_noise_floor_factor_follows_the_larger_part() -> None:
    """At the floor when what the model misses is not the larger part of the residual's
    variance: ``rms^2 - f^2 <= explained_share rms^2``, so ``rms <= f / sqrt(1 - share)``."""
    assert DEFAULT_SETTINGS.floor_factor == pytest.approx(math.sqrt(2.0))
    assert DiagnoseSettings(explained_share=0.75).floor_factor == pytest.approx(2.0)


def test_a_loop_element_is_kept_when_it_carries_the_larger_part() -> None:
    """A drive limit or a command delay must leave at most ``1 - explained_share`` of the
    squared error the loop without it leaves: one half by default, a quarter when three
    quarters of the error must go."""
    assert DEFAULT_SETTINGS.limit_margin == 0.5
    assert DiagnoseSettings(explained_share=0.75).limit_margin == pytest.approx(0.25)
    assert "limit_margin" not in {f.name for f in dataclasses.fields(DiagnoseSettings)}


def test_the_highest_coupling_damping_gives_a_peak_of_the_larger_part() -> None:
    """At the highest damping ratio the resonance's peak stands ``floor_factor`` times above
    the static level: it carries the larger part of the response's power there."""
    low, high = DEFAULT_SETTINGS.compliance_zeta_range
    assert low == DEFAULT_SETTINGS.compliance_zeta_min
    peak = 1.0 / (2.0 * high * math.sqrt(1.0 - high**2))
    assert peak == pytest.approx(DEFAULT_SETTINGS.floor_factor)
    assert 1.0 - 1.0 / peak**2 == pytest.approx(DEFAULT_SETTINGS.explained_share)
    # more of the power asked of the peak: a lower damping
    assert DiagnoseSettings(explained_share=0.75).compliance_zeta_range[1] < high

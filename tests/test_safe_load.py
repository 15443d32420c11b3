"""Model files from users: a hostile torch archive is refused, with the reason and without
torch's advice to load it unsafely."""

from __future__ import annotations

import io
import os
import re

import pytest
import torch

from fricbench._safe_load import UnsafeFileError, load_tensors


class _Calls:
    """Pickles as a call of ``os.system`` (what a hostile checkpoint does)."""

    def __reduce__(self) -> tuple[object, tuple[str]]:
        return os.system, ("echo this must never run",)


class _Object:
    """An arbitrary class: loading it would import this module."""


def _saved(obj: object) -> bytes:
    buf = io.BytesIO()
    torch.save(obj, buf)
    return buf.getvalue()


@pytest.mark.parametrize(("payload", "named"), [
    ({"w": torch.zeros(2), "x": _Calls()}, r"(posix|nt)\.system"),
    ({"w": torch.zeros(2), "o": _Object()}, r"test_safe_load\._Object"),
])
def test_a_hostile_file_is_refused_without_advice_to_load_it(payload: object,
                                                             named: str) -> None:
    with pytest.raises(UnsafeFileError) as info:
        load_tensors(_saved(payload), "evil.pt")
    text = str(info.value)
    assert text.startswith("evil.pt: refused: it holds a reference to the Python object ")
    assert re.search(named, text), text
    assert "never runs code from a file" in text
    # torch's advice: load with weights_only=False, or allow-list the object; neither here
    for advice in ("weights_only` set to `False", "weights_only=False", "add_safe_globals",
                   "safe_globals", "trusted source", "will likely succeed"):
        assert advice not in text, text


def test_plain_weights_still_load() -> None:
    state = load_tensors(_saved({"w": torch.ones(3)}), "ok.pt")
    assert torch.equal(state["w"], torch.ones(3))

"""Bounded, code-free reading of model files handed in by users (predictors, RL policies).

Nothing read here is unpickled or imported. Every size is checked against a cap before the
bytes are inflated or allocated: a file by its size on disk, a zip archive by the size of its
directory and then its members by their declared sizes (read through a bounded reader, so a
member that inflates past its declaration is refused), the records of a torch weights archive
the same way, and the tensors it holds by their element count. The functions raise
:class:`UnsafeFileError` (a ``ValueError``) whose message starts with the ``where`` string
given by the caller (the file and, inside an archive, the member); each loader re-raises it
as its own error type.
"""

from __future__ import annotations

import io
import json
import os
import pickle
import re
import stat
import struct
import zipfile
import zlib
from collections import Counter
from collections.abc import Collection
from pathlib import Path
from typing import Any

import torch

__all__ = ["MAX_MODEL_BYTES", "MAX_JSON_BYTES", "MAX_DIRECTORY_BYTES", "UnsafeFileError",
           "read_file", "parse_json", "read_members", "load_tensors"]

#: Cap on the uncompressed bytes of one model file (all members together; for a policy, the
#: weights file), 256 MiB: a hundred times the largest model fricbench trains.
MAX_MODEL_BYTES = 256 * 2**20

#: Cap on a JSON configuration, 1 MiB.
MAX_JSON_BYTES = 2**20

#: Cap on a zip archive's central directory, 1 MiB (some 20,000 members): :mod:`zipfile`
#: builds an object per member before any of them can be checked.
MAX_DIRECTORY_BYTES = 2**20

_CHUNK = 2**20
_COMPRESSIONS = {zipfile.ZIP_STORED: "stored", zipfile.ZIP_DEFLATED: "deflate"}


class UnsafeFileError(ValueError):
    """A model file that is malformed or exceeds a size cap; the message names it."""


def read_file(path: str | os.PathLike[str], limit: int) -> bytes:
    """Read a regular file of at most ``limit`` bytes.

    Raises
    ------
    FileNotFoundError
        ``path`` does not exist.
    UnsafeFileError
        ``path`` is not a regular file (a folder, a FIFO, a device), is larger than ``limit``
        bytes, or cannot be read.
    """
    path = Path(path)
    try:
        # O_NONBLOCK: opening a FIFO must not wait for a writer before we can refuse it
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    except FileNotFoundError:
        raise
    except OSError as exc:
        raise UnsafeFileError(f"{path}: cannot open ({exc.strerror or exc})") from None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            raise UnsafeFileError(f"{path}: not a regular file")
        if st.st_size > limit:
            raise UnsafeFileError(f"{path}: {st.st_size} bytes; expected at most {limit} bytes")
        with os.fdopen(fd, "rb", closefd=False) as fh:
            data = fh.read(limit + 1)
    except OSError as exc:
        raise UnsafeFileError(f"{path}: cannot read ({exc.strerror or exc})") from None
    finally:
        os.close(fd)
    if len(data) > limit:  # grew since stat
        raise UnsafeFileError(f"{path}: more than {limit} bytes")
    return data


def parse_json(raw: bytes, where: str) -> Any:
    """Decode UTF-8 JSON text of at most :data:`MAX_JSON_BYTES`.

    Raises
    ------
    UnsafeFileError
        Too large, not UTF-8, not JSON, nested too deeply, or a number too long to convert.
    """
    if len(raw) > MAX_JSON_BYTES:
        raise UnsafeFileError(f"{where}: {len(raw)} bytes; expected at most {MAX_JSON_BYTES} "
                              "bytes of JSON")
    try:
        return json.loads(raw.decode("utf-8"))
    except UnicodeDecodeError as exc:
        raise UnsafeFileError(f"{where}: not UTF-8 text ({exc})") from None
    except RecursionError:
        raise UnsafeFileError(f"{where}: JSON nested too deeply") from None
    except ValueError as exc:  # JSONDecodeError, and integers longer than Python converts
        raise UnsafeFileError(f"{where}: not valid JSON ({exc})") from None


def _directory_size(data: bytes) -> int | None:
    """Size of the central directory a zip reader will parse (``None``: no end record).

    Finds the end-of-central-directory record as :mod:`zipfile` does (at the very end, else
    the last one within a maximal comment), and its zip64 variant when the sizes overflow.
    """
    sig, sig64, loc64 = b"PK\x05\x06", b"PK\x06\x06", b"PK\x06\x07"
    if len(data) >= 22 and data[-22:-18] == sig and data[-2:] == b"\0\0":
        end = len(data) - 22
    else:
        end = data.rfind(sig, max(0, len(data) - 22 - 0xFFFF))
        if end < 0 or end + 22 > len(data):
            return None
    (size,) = struct.unpack_from("<I", data, end + 12)
    if size == 0xFFFFFFFF and end >= 20 and data[end - 20:end - 16] == loc64:
        (offset,) = struct.unpack_from("<Q", data, end - 12)
        if offset + 56 <= len(data) and data[offset:offset + 4] == sig64:
            (size,) = struct.unpack_from("<Q", data, offset + 40)
    return int(size)


def _open_zip(data: bytes, where: str) -> zipfile.ZipFile:
    size = _directory_size(data)
    if size is not None and size > MAX_DIRECTORY_BYTES:
        raise UnsafeFileError(f"{where}: zip directory of {size} bytes; expected at most "
                              f"{MAX_DIRECTORY_BYTES} bytes")
    return zipfile.ZipFile(io.BytesIO(data))


def _check_infos(zf: zipfile.ZipFile, where: str, limit: int) -> list[zipfile.ZipInfo]:
    infos = zf.infolist()
    counts = Counter(i.filename for i in infos)
    dupes = sorted(n for n, c in counts.items() if c > 1)
    if dupes:
        raise UnsafeFileError(f"{where}: members {dupes} appear more than once")
    total = 0
    for info in infos:
        if info.flag_bits & 0x1:
            raise UnsafeFileError(f"{where}: member {info.filename!r} is encrypted")
        if info.compress_type not in _COMPRESSIONS:
            raise UnsafeFileError(
                f"{where}: member {info.filename!r} uses compression method "
                f"{info.compress_type}; expected {' or '.join(_COMPRESSIONS.values())}")
        total += info.file_size
        if total > limit:
            raise UnsafeFileError(f"{where}: members declare {total} bytes uncompressed (at "
                                  f"{info.filename!r}); expected at most {limit} bytes")
    return infos


def _read_bounded(zf: zipfile.ZipFile, info: zipfile.ZipInfo, where: str) -> bytes:
    """Read one member, refusing it as soon as it yields more than its declared size."""
    out = bytearray()
    with zf.open(info) as fh:
        while chunk := fh.read(_CHUNK):
            out += chunk
            if len(out) > info.file_size:
                raise UnsafeFileError(f"{where}: member {info.filename!r} inflates past its "
                                      f"declared {info.file_size} bytes")
    if len(out) != info.file_size:
        raise UnsafeFileError(f"{where}: member {info.filename!r} holds {len(out)} bytes but "
                              f"declares {info.file_size}")
    return bytes(out)


def read_members(data: bytes, where: str, expected: Collection[str],
                 limit: int = MAX_MODEL_BYTES) -> dict[str, bytes]:
    """Read the members of a zip archive that must hold exactly ``expected``.

    Parameters
    ----------
    data : bytes
        The archive's bytes (see :func:`read_file`).
    where : str
        Prefix of every error message (the file's name).
    expected : collection of str
        The member names the archive must hold, no more and no fewer.
    limit : int
        Cap on the declared uncompressed bytes of all members together.

    Raises
    ------
    UnsafeFileError
        Not a zip archive, unexpected, missing, duplicate or encrypted members, a compression
        method other than stored or deflate, declared sizes above ``limit``, or a member whose
        data does not match its declaration.
    """
    try:
        with _open_zip(data, where) as zf:
            infos = _check_infos(zf, where, limit)
            names = {i.filename for i in infos}
            if names != set(expected):
                raise UnsafeFileError(
                    f"{where}: members {sorted(names)}; expected exactly {sorted(expected)} "
                    f"(missing {sorted(set(expected) - names)}, unexpected "
                    f"{sorted(names - set(expected))})")
            return {i.filename: _read_bounded(zf, i, where) for i in infos}
    except (zipfile.BadZipFile, zlib.error, EOFError, NotImplementedError) as exc:
        raise UnsafeFileError(f"{where}: not a valid zip archive ({exc})") from None


def _refusal(message: str) -> str:
    """Why torch's weights-only unpickler refused a file, without its advice (to load the file
    with ``weights_only=False``, or to allow-list the object it names: either runs the file's
    code)."""
    # torch: "... unsupported GLOBAL posix.system whose module posix is blocked" or
    # "Unsupported global: GLOBAL __main__.Obj was not an allowed global by default"
    named = re.search(r"GLOBAL ([\w.]+)", message)
    if named:
        return (f"it holds a reference to the Python object {named.group(1)}, which loading "
                "would import and may call")
    detail = re.search(r"WeightsUnpickler error: ([^\n]*?)(?:\s*Please use.*)?$", message,
                       re.MULTILINE)
    reason = detail.group(1).strip() if detail else "its pickle holds more than tensors"
    return f"not a plain weights file ({reason})"


def load_tensors(raw: bytes, where: str, limit: int = MAX_MODEL_BYTES) -> dict[str, torch.Tensor]:
    """Load a ``torch.save`` of a ``dict[str, Tensor]`` with ``weights_only=True``, bounded.

    The archive's records are checked by declared size before torch inflates them (torch
    inflates deflated records to their declared size), and the tensors are checked for type,
    layout, a floating dtype and their total size (a view with zero strides can describe far
    more elements than its storage holds).

    Raises
    ------
    UnsafeFileError
        Anything but a current-format torch archive of a string-keyed dict of dense floating
        tensors within ``limit`` bytes.
    """
    try:
        with _open_zip(raw, where) as zf:
            _check_infos(zf, where, limit)
    except (zipfile.BadZipFile, EOFError) as exc:
        raise UnsafeFileError(f"{where}: unreadable torch weights (not a torch zip "
                              f"archive: {exc})") from None
    try:
        state = torch.load(io.BytesIO(raw), map_location="cpu", weights_only=True)
    except pickle.UnpicklingError as exc:  # torch's weights-only unpickler refused the file
        raise UnsafeFileError(f"{where}: refused: {_refusal(str(exc))}; fricbench reads model "
                              "files as plain tensors only (torch.load with weights_only=True) "
                              "and never runs code from a file") from None
    except Exception as exc:  # noqa: BLE001 - torch raises many unrelated types on corrupt input
        raise UnsafeFileError(f"{where}: unreadable torch weights "
                              f"({type(exc).__name__}: {exc})") from None
    if not isinstance(state, dict):
        raise UnsafeFileError(f"{where}: holds a {type(state).__name__}; expected a "
                              "state_dict (a dict of tensors)")
    total = 0
    for key, value in state.items():
        if not isinstance(key, str):
            raise UnsafeFileError(f"{where}: key {key!r} is a {type(key).__name__}; expected "
                                  "string keys")
        if not isinstance(value, torch.Tensor):
            raise UnsafeFileError(f"{where}: {key!r} is a {type(value).__name__}; expected a "
                                  "tensor")
        if value.layout != torch.strided or value.is_quantized:
            raise UnsafeFileError(f"{where}: tensor {key!r} has layout {value.layout}; "
                                  "expected a dense (strided) tensor")
        if not value.is_floating_point():
            raise UnsafeFileError(f"{where}: tensor {key!r} has dtype {value.dtype}; expected "
                                  "a floating dtype (float32 or float64)")
        total += value.numel() * value.element_size()
        if total > limit:
            raise UnsafeFileError(f"{where}: tensors describe more than {limit} bytes (at "
                                  f"{key!r}, shape {tuple(value.shape)})")
    return state

"""Output files written atomically: into a temporary file beside the target, then renamed, so a crash or a
failed frame never leaves a half-written file where a good one (or none) was."""
from __future__ import annotations

import os
import tempfile


def atomic_write(path: str, write_to) -> None:
    """Call `write_to(temporary_path)`, then move the result over `path`; on error nothing is left behind."""
    path = os.fspath(path)
    folder = os.path.dirname(os.path.abspath(path)) or "."
    os.makedirs(folder, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=".penumbra-", suffix=os.path.splitext(path)[1], dir=folder)
    os.close(fd)
    try:
        write_to(tmp)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def write_atomic(path: str, data: str | bytes) -> None:
    """Text (UTF-8, newlines as given) or bytes to `path`, atomically."""
    def write_to(tmp):
        if isinstance(data, bytes):
            with open(tmp, "wb") as f:
                f.write(data)
        else:
            with open(tmp, "w", encoding="utf-8", newline="") as f:
                f.write(data)
    atomic_write(path, write_to)

"""Output files written atomically: into a temporary file beside the target, then renamed, so a crash or a
failed frame never leaves a half-written file where a good one (or none) was. `check_output_file` and
`check_output_folder` refuse an output that cannot be written before any work is done."""
from __future__ import annotations

import os
import tempfile


class OutputError(ValueError):
    """An output path that cannot be written; the message is one line naming the path."""


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def atomic_write(path: str, write_to) -> None:
    """Call `write_to(temporary_path)`, then move the result over `path`; on error nothing is left behind.
    The file gets the mode any other new file would (0666 less the umask): mkstemp creates it 0600."""
    path = os.fspath(path)
    folder = os.path.dirname(os.path.abspath(path)) or "."
    try:
        os.makedirs(folder, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=".penumbra-", suffix=os.path.splitext(path)[1], dir=folder)
    except OSError as exc:
        raise OutputError(f"cannot write '{path}': {exc.strerror or exc}") from None
    os.close(fd)
    try:
        write_to(tmp)
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, path)
    except BaseException as exc:
        if os.path.exists(tmp):
            os.unlink(tmp)
        if isinstance(exc, OSError):
            raise OutputError(f"cannot write '{path}': {exc.strerror or exc}") from None
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


def _check_folder(folder: str, shown: str) -> None:
    """`folder` exists and takes a new file, or can be created: probed with a real file, since os.access
    says yes to root on a read-only mount's permission bits and knows nothing of quotas or ACLs."""
    existing = folder
    while not os.path.exists(existing):
        parent = os.path.dirname(existing)
        if parent == existing:
            break
        existing = parent
    if not os.path.isdir(existing):
        raise OutputError(f"cannot write '{shown}': '{existing}' is a file, not a folder")
    try:
        fd, probe = tempfile.mkstemp(prefix=".penumbra-probe-", dir=existing)
    except OSError as exc:
        raise OutputError(f"cannot write '{shown}': folder '{existing}' is not writable "
                          f"({exc.strerror or exc})") from None
    os.close(fd)
    os.unlink(probe)


def check_output_file(path: str) -> str:
    """Refuse (OutputError) a file output that is a folder or whose folder cannot be written; returns the
    absolute path. Creates nothing."""
    full = os.path.abspath(os.fspath(path))
    if os.path.isdir(full):
        raise OutputError(f"output '{path}' is a folder; give a file name")
    _check_folder(os.path.dirname(full), path)
    return full


def check_output_folder(path: str) -> str:
    """Refuse (OutputError) an output folder that is a file or cannot be written or created; returns the
    absolute path. Creates nothing."""
    full = os.path.abspath(os.fspath(path))
    if os.path.exists(full) and not os.path.isdir(full):
        raise OutputError(f"output folder '{path}' is a file; give a folder")
    _check_folder(full, path)
    return full

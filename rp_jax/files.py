"""Files written whole or not at all, readable by others: the one home for atomic writes.

Every file the project writes (records' side files, layouts, checkpoints' companions,
reports, figures, models) goes through a temporary name in the same folder and an
``os.replace`` onto the final name, so a killed run leaves the old file or the new one,
never half of one. The temporary file is created with the permissions a plain
``open(path, "w")`` gives (0666 less the umask: 0644 under the usual umask 022), not
``tempfile``'s private 0600, so others can read what the project writes. On failure the
temporary file is removed and the final name is untouched.

``replacing(path)`` is the general form: it yields a temporary path for any writer that
wants a file name (``cv2.imwrite``, ``np.savez``, ``savefig``, h5py); ``write_bytes``,
``write_text`` and ``write_json`` are the common cases. ``publish_dir`` does the same for a
folder written in full (a COLMAP model).

``OutputFolder`` is a command's ``--out``: it refuses, before any work, to replace a file the
project did not write there (a user's own ``summary.json``), unless told to overwrite; it
records what it wrote (``.rp_jax_outputs.json``: name, size, modification time) so that a
second run replaces its own outputs without asking; and a run that fails leaves nothing of
itself behind (what it wrote is removed, and the folder if it made it). ``folder_problem``
says, before any work, why a folder could not be created or written (the experiments ask
it of ``--workdir``).
"""

from __future__ import annotations

import contextlib
import json
import os
import secrets
import shutil
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

__all__ = [
    "OUTPUTS_RECORD",
    "FolderNotWritableError",
    "OutputExistsError",
    "OutputFolder",
    "folder_problem",
    "publish_dir",
    "replacing",
    "write_bytes",
    "write_json",
    "write_text",
]

OUTPUTS_RECORD = ".rp_jax_outputs.json"


def _umask() -> int:
    """The process umask, read without changing it where Linux tells it (/proc): setting it
    to 0 and back, the only portable way, races with other threads creating files."""
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError):
        pass
    mask = os.umask(0)
    os.umask(mask)
    return mask


def _create_beside(path: Path, suffix: str) -> Path:
    """A new empty file beside ``path`` with a hidden random name, created 0666 less the
    umask (what a plain ``open`` gives; ``tempfile.mkstemp`` would make it 0600)."""
    for _ in range(100):
        tmp = path.with_name(f".{path.name}.{secrets.token_hex(4)}{suffix}")
        try:
            os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
            return tmp
        except FileExistsError:
            continue
    raise FileExistsError(f"no free temporary name beside {path}")


def _readable(path: Path, *, directory: bool = False) -> None:
    """The permissions of a plain ``open``/``mkdir``: 0666 / 0777 less the umask."""
    os.chmod(path, (0o777 if directory else 0o666) & ~_umask())


@contextlib.contextmanager
def replacing(path: str | os.PathLike, *, suffix: str = ".tmp") -> Iterator[Path]:
    """Yields a temporary path beside ``path``; on success it becomes ``path``.

    Args:
      path: the final file; its folder is created if needed.
      suffix: the temporary name's suffix. The default is one no reader globs for (a
        run killed mid-write leaves a hidden ``.NAME.XXXX.tmp`` that no ``*.jpg`` picks
        up); writers that choose the format by extension are given it explicitly instead
        (``savefig(tmp, format="png")``, ``cv2.imencode`` + ``write_bytes``).

    Writers that append their own extension (``np.savez`` adds ``.npz``) are given an
    open file object instead of the name.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = _create_beside(path, suffix)
    try:
        yield tmp
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def write_bytes(path: str | os.PathLike, data: bytes) -> Path:
    """Writes ``data`` to ``path`` atomically; returns ``path``."""
    with replacing(path) as tmp:
        tmp.write_bytes(data)
    return Path(path)


def write_text(path: str | os.PathLike, text: str) -> Path:
    """Writes ``text`` (UTF-8) to ``path`` atomically; returns ``path``."""
    return write_bytes(path, text.encode("utf-8"))


def write_json(path: str | os.PathLike, data: Any, *, indent: int | None = 2, **kwargs) -> Path:
    """Writes ``data`` as JSON (a final newline) to ``path`` atomically; returns ``path``."""
    return write_text(path, json.dumps(data, indent=indent, **kwargs) + "\n")


def publish_dir(tmp_dir: str | os.PathLike, path: str | os.PathLike) -> Path:
    """Moves a fully written folder ``tmp_dir`` onto ``path`` (replacing an older one).

    ``tmp_dir`` must be on the same file system (make it beside ``path``). The folder and
    its files get plain permissions first. An older ``path`` is moved aside just before the
    rename and removed after it, so ``path`` is never half-written while it exists.
    """
    tmp_dir, path = Path(tmp_dir), Path(path)
    _readable(tmp_dir, directory=True)
    for root, dirs, files in os.walk(tmp_dir):
        for d in dirs:
            _readable(Path(root) / d, directory=True)
        for f in files:
            _readable(Path(root) / f)
    old = None
    if path.exists():
        old = Path(tempfile.mkdtemp(prefix=f".{path.name}.old.", dir=path.parent))
        os.replace(path, old / path.name)
    os.replace(tmp_dir, path)
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)
    return path


class OutputExistsError(FileExistsError):
    """An output would replace a file or folder that the project did not write there."""


class FolderNotWritableError(PermissionError):
    """An output folder cannot be created, or this process may not write in it."""


def folder_problem(path: str | os.PathLike) -> str | None:
    """Why ``path`` cannot be a folder this process writes in, or None if it can.

    Read before any work, so that a run stops at once instead of after hours (or with a
    traceback from the first ``mkdir``): a file at ``path``, a file among its parents, or no
    permission to write in it or in its nearest existing parent (``os.access``: a read-only
    mount counts; a process with root's rights may pass where a plain user would not). Reads
    only: nothing is created. The phrase follows the path in a message.
    """
    path = Path(path)
    if path.exists():
        if not path.is_dir():
            return "is a file, not a folder"
        return None if os.access(path, os.W_OK | os.X_OK) else "is a folder you may not write in"
    parent = path.absolute().parent
    while not parent.exists() and parent != parent.parent:
        parent = parent.parent
    if not parent.is_dir():
        return f"cannot be created: {parent} is a file"
    if not os.access(parent, os.W_OK | os.X_OK):
        return f"cannot be created: you may not write in {parent}"
    return None


def _state(path: Path) -> dict | None:
    """What identifies a written output: a folder, or a file's size and modification time."""
    try:
        st = path.stat()
    except OSError:
        return None
    if path.is_dir():
        return {"dir": True}
    return {"size": st.st_size, "mtime_ns": st.st_mtime_ns}


class OutputFolder:
    """A command's output folder (see the module docstring); a context manager.

    ``with OutputFolder(out, names, overwrite=False) as folder:`` checks, on entering, that
    no name in ``names`` (files or folders inside ``out``) exists there unless this project
    wrote it (its record says so and the file is as it was written) or ``overwrite`` is
    set. On a clean exit it records every name that exists. On an exception it removes every
    name that the run created or changed, and ``out`` itself if the run created it and it
    is empty, then lets the exception go on. The folder is not created here: the writers
    create it with their first file.

    Attributes:
      path: the folder.
    """

    def __init__(self, path: str | os.PathLike, names, *, overwrite: bool = False,
                 flag: str = "--out"):
        self.path = Path(path)
        self.names = list(dict.fromkeys(str(n) for n in names))
        self.overwrite = overwrite
        self.flag = flag
        self._created = False
        self._before: dict[str, dict | None] = {}

    def _record(self) -> dict:
        try:
            record = json.loads((self.path / OUTPUTS_RECORD).read_text())
        except (OSError, ValueError):
            return {}
        return record if isinstance(record, dict) else {}

    def ours(self, name: str) -> bool:
        """Whether ``name`` in the folder is as this project wrote it."""
        state = _state(self.path / name)
        return state is not None and self._record().get(name) == state

    def __enter__(self) -> OutputFolder:
        problem = folder_problem(self.path)
        if problem is not None:
            error = OutputExistsError if self.path.exists() and not self.path.is_dir() \
                else FolderNotWritableError
            raise error(f"{self.flag} {self.path} {problem}")
        if not self.overwrite:
            theirs = [n for n in self.names if (self.path / n).exists() and not self.ours(n)]
            if theirs:
                shown = ", ".join(theirs[:3]) + (f" and {len(theirs) - 3} more"
                                                 if len(theirs) > 3 else "")
                raise OutputExistsError(
                    f"{self.flag} {self.path} already holds {shown}, not written by this "
                    "command: give another folder, move them, or add --overwrite")
        self._created = not self.path.exists()
        self._before = {n: _state(self.path / n) for n in self.names}
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is None:
            record = self._record()
            record.update({n: s for n in self.names if (s := _state(self.path / n))})
            if record:
                write_json(self.path / OUTPUTS_RECORD, record)
            return
        for n in self.names:
            p = self.path / n
            if _state(p) is not None and _state(p) != self._before.get(n):
                if p.is_dir() and not p.is_symlink():
                    shutil.rmtree(p, ignore_errors=True)
                else:
                    p.unlink(missing_ok=True)
        if self._created and self.path.is_dir():
            with contextlib.suppress(OSError):
                if not any(self.path.iterdir()):
                    self.path.rmdir()

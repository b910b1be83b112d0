"""Writing results to files, atomically.

Every writer first writes a temporary file in the destination folder and then renames it
over the destination (:func:`os.replace`, atomic on POSIX and Windows), so an interrupted
run never leaves a half-written file: the destination holds either the old content or the
new one.
"""

from __future__ import annotations

import contextlib
import csv
import io
import json
import os
import shutil
import tempfile
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from .errors import FieldError

if TYPE_CHECKING:  # matplotlib is imported only by those who draw
    from matplotlib.figure import Figure

__all__ = [
    "atomic_path",
    "check_output_file",
    "check_output_folder",
    "json_text",
    "make_output_folder",
    "save_figure",
    "staged_folder",
    "write_csv",
    "write_json",
    "write_text",
]


def check_output_folder(
    path: str | os.PathLike[str], field: str, *, new: bool = False, overwrite: bool = False
) -> None:
    """Fail early, creating nothing, if the folder ``path`` could not be created or written.

    Parameters
    ----------
    path : str or path-like
        The folder (it may not exist yet).
    field : str
        The argument that named it, for the error.
    new : bool, default False
        Also refuse a folder that already holds files, unless ``overwrite``: results are
        never replaced unasked.
    overwrite : bool, default False
        With ``new``, accept a folder that holds files (the user asked to replace them).

    Raises
    ------
    FieldError
        If an existing part of the path is not a folder, or is not writable, or (``new``)
        the folder holds files and ``overwrite`` is not set.
    """
    folder = Path(path)
    if new and not overwrite and folder.is_dir() and _holds_files(folder):
        raise FieldError(
            field,
            f"{str(folder)!r} already holds files; choose a new or empty folder, or "
            "replace its files with --force (in Python: overwrite=True)",
        )
    probe = folder
    while not probe.exists():
        if probe.parent == probe:
            break
        probe = probe.parent
    if not probe.is_dir():
        raise FieldError(field, f"{str(probe)!r} exists and is not a folder")
    if not os.access(probe, os.W_OK | os.X_OK):
        raise FieldError(field, f"cannot write in {str(probe)!r}")


def check_output_file(
    path: str | os.PathLike[str], field: str, *, overwrite: bool = False
) -> Path:
    """Fail early, writing nothing, if the file ``path`` could not be written (then write
    it with :func:`write_json` or :func:`write_text`, atomically).

    Parameters
    ----------
    path : str or path-like
        The file (it may not exist yet); its folder must exist.
    field : str
        The argument that named it, for the error.
    overwrite : bool, default False
        Accept an existing file (the user asked to replace it).

    Returns
    -------
    pathlib.Path
        The file's path.

    Raises
    ------
    FieldError
        If the path is a folder, the file exists and ``overwrite`` is not set, or its
        folder is missing or not writable.
    """
    dest = Path(path)
    if dest.is_dir():
        raise FieldError(field, f"{str(dest)!r} is a folder; give a file name")
    if (dest.exists() or dest.is_symlink()) and not overwrite:
        raise FieldError(
            field,
            f"{str(dest)!r} already exists; choose a new file name, or replace it with "
            "--force (in Python: overwrite=True)",
        )
    folder = dest.parent
    if not folder.is_dir():
        raise FieldError(field, f"folder {str(folder)!r} does not exist")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise FieldError(field, f"cannot write in {str(folder)!r}")
    return dest


def _holds_files(folder: Path) -> bool:
    """Whether ``folder`` holds anything but staged folders left by killed writers."""
    return any(not _stale_stage(entry) for entry in folder.iterdir())


def make_output_folder(path: str | os.PathLike[str], field: str) -> Path:
    """Create the folder ``path`` (and its parents) if missing.

    Parameters
    ----------
    path : str or path-like
        The folder.
    field : str
        The argument that named it, for the error.

    Returns
    -------
    pathlib.Path
        The folder.

    Raises
    ------
    FieldError
        If it cannot be created.
    """
    out = Path(path)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise FieldError(field, f"cannot create folder {str(out)!r}: {exc.strerror}") from exc
    return out


#: Prefix of the hidden folder in which a result set is written before it is moved into
#: place (:func:`staged_folder`), followed by the writing process's id.
STAGE_PREFIX = ".crlbswarm-partial-"


@contextlib.contextmanager
def staged_folder(
    path: str | os.PathLike[str], field: str, *, overwrite: bool = False, marker: str = ""
) -> Iterator[Path]:
    """Yield a hidden folder to write a set of files in; move them into ``path`` when the
    block succeeds, remove them if it raises.

    The folder is refused at the start if it holds files and ``overwrite`` is not set
    (:func:`check_output_folder`). A missing ``path`` is staged beside it, in its parent,
    and the staged folder is renamed to ``path`` at the end: one atomic step, so after a
    crash ``path`` is absent or complete. An existing ``path`` (empty, or holding files the
    user asked to replace; a mount point or a link to a folder as well) is never replaced,
    so its owner, mode and links are kept: the set is staged inside it and its files are
    moved up one by one, ``marker`` (the file whose presence marks a complete set) removed
    first and moved in last. Staged folders left by a killed process are removed the next
    time a set is written there. If the files cannot be moved into place, they are kept
    where they were staged and the error says where.

    Parameters
    ----------
    path : str or path-like
        The destination folder.
    field : str
        The argument that named it, for errors.
    overwrite : bool, default False
        Replace the files of the same names in a folder that already holds files.
    marker : str, optional
        Name of the file that marks a complete set.

    Yields
    ------
    pathlib.Path
        The staged folder to write in.

    Raises
    ------
    FieldError
        If the folder cannot be written, or holds files and ``overwrite`` is not set, or the
        finished set cannot be moved into it.
    """
    dest = Path(os.path.abspath(path))  # "." and "sub/.." have a parent to stage in
    check_output_folder(dest, field, new=True, overwrite=overwrite)
    exists = dest.is_dir()
    home = dest if exists else make_output_folder(dest.parent, field)
    _remove_stale_stages(home)
    try:
        stage = Path(tempfile.mkdtemp(prefix=f"{STAGE_PREFIX}{os.getpid()}-", dir=home))
    except OSError as exc:
        raise FieldError(field, f"cannot write in {str(home)!r}: {exc.strerror}") from None
    try:
        yield stage
        stage.chmod(0o755)  # mkdtemp makes 0700; results are meant to be shared
    except BaseException:
        shutil.rmtree(stage, ignore_errors=True)
        raise
    try:
        if exists:
            _move_files(stage, dest, marker)
        else:
            os.rename(stage, dest)  # fails if something created dest meanwhile
    except OSError as exc:
        raise FieldError(
            field,
            f"the results could not be moved into {str(dest)!r} ({exc.strerror}); they are "
            f"kept in {str(stage)!r}",
        ) from None


def _move_files(stage: Path, dest: Path, marker: str) -> None:
    """Move the staged files up into ``dest``, the marker removed first and moved last."""
    names = sorted(p.name for p in stage.iterdir())
    if marker in names:
        names.remove(marker)
        names.append(marker)
        (dest / marker).unlink(missing_ok=True)
    for name in names:
        if (stage / name).is_dir() and (dest / name).is_dir() and not (dest / name).is_symlink():
            shutil.rmtree(dest / name)  # a folder of the set (the user asked to replace it)
        os.replace(stage / name, dest / name)
    stage.rmdir()


def _stale_stage(entry: Path) -> bool:
    """Whether ``entry`` is a staged folder whose writing process no longer runs."""
    if not entry.name.startswith(STAGE_PREFIX):
        return False
    pid = entry.name[len(STAGE_PREFIX) :].split("-")[0]
    return pid.isdigit() and not _running(int(pid))


def _remove_stale_stages(folder: Path) -> None:
    """Remove the staged folders in ``folder`` whose writing process no longer runs."""
    for stale in folder.glob(f"{STAGE_PREFIX}*"):
        if _stale_stage(stale):
            shutil.rmtree(stale, ignore_errors=True)


def _running(pid: int) -> bool:
    """Whether a process ``pid`` exists (on this machine)."""
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:  # exists, but not ours (PermissionError), or not POSIX
        return True
    return True


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike[str]) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; rename it to ``path`` if the block succeeds.

    The temporary file keeps the destination's suffix (so writers that infer the format
    from it still work) and is removed if the block raises.

    Parameters
    ----------
    path : str or path-like
        Final destination. Its folder must exist.

    Yields
    ------
    pathlib.Path
        The temporary path to write.
    """
    dest = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{dest.name}.", suffix=dest.suffix, dir=dest.parent)
    os.close(fd)
    tmp_path = Path(tmp)
    try:
        yield tmp_path
        os.chmod(tmp_path, 0o644)  # mkstemp makes 0600; results are meant to be shared
        os.replace(tmp_path, dest)
    except BaseException:
        tmp_path.unlink(missing_ok=True)
        raise


def write_text(path: str | os.PathLike[str], text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` atomically.

    Parameters
    ----------
    path : str or path-like
        Destination file.
    text : str
        Content.
    """
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")


def _csv_text(columns: Mapping[str, Any]) -> str:
    names = list(columns)
    arrays = [np.asarray(columns[name]) for name in names]
    lengths = {a.shape[0] for a in arrays}
    if len(lengths) != 1 or any(a.ndim != 1 for a in arrays):
        raise FieldError("columns", "every column must be 1-D and of the same length")
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(names)
    for row in zip(*arrays, strict=True):
        writer.writerow([_cell(x) for x in row])
    return buf.getvalue()


def _cell(value: Any) -> Any:
    """A CSV cell: floats in their shortest round-trip form, NaN and infinities empty."""
    if isinstance(value, float | np.floating):
        return repr(float(value)) if np.isfinite(value) else ""
    return value


def write_csv(path: str | os.PathLike[str], columns: Mapping[str, Any]) -> None:
    """Write equal-length 1-D columns as CSV atomically: one header row, then the values.

    Floats are written with ``repr`` (shortest round-trip form), so reading the file back
    gives the same numbers bit for bit; NaN and infinities (a quantity that does not exist
    for that row, such as the convergence time of a run that did not converge, or the
    clearance of a scene without obstacles) are written as empty cells.

    Parameters
    ----------
    path : str or path-like
        Destination file.
    columns : mapping of str to 1-D array_like
        Column name to values, in order.
    """
    write_text(path, _csv_text(columns))


def _json_safe(data: Any) -> Any:
    """Replace NaN and infinities (not valid JSON) by ``None``, recursively."""
    if isinstance(data, dict):
        return {k: _json_safe(v) for k, v in data.items()}
    if isinstance(data, list | tuple):
        return [_json_safe(v) for v in data]
    if isinstance(data, float | np.floating):
        return float(data) if np.isfinite(data) else None
    if isinstance(data, np.integer):
        return int(data)
    return data


def json_text(data: Any) -> str:
    """Indented, strictly valid JSON: NaN and infinities become ``null``.

    Parameters
    ----------
    data : object
        Dictionaries, lists, strings, numbers (NumPy scalars included), booleans, None.

    Returns
    -------
    str
        The JSON text, ending with a newline.
    """
    return json.dumps(_json_safe(data), indent=2, allow_nan=False) + "\n"


def write_json(path: str | os.PathLike[str], data: Any) -> None:
    """Write ``data`` as indented JSON atomically (NaN and infinities become ``null``).

    Parameters
    ----------
    path : str or path-like
        Destination file.
    data : object
        JSON-serialisable data.
    """
    write_text(path, json_text(data))


def save_figure(fig: Figure, path: str | os.PathLike[str], dpi: int = 150) -> None:
    """Save a Matplotlib figure atomically; the format follows the file suffix.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        The figure.
    path : str or path-like
        Destination file (``.png``, ``.pdf``, ``.svg``, ...).
    dpi : int, default 150
        Resolution of raster formats.
    """
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=dpi)

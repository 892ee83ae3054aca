"""Files a command writes, written safely: output paths, claims, atomic writes, JSON.

Every file is written through a temporary file in its own directory and moved
into place by :func:`os.replace`, so a killed run leaves the previous complete
file or none (:func:`atomic_write_text`, :func:`replacing`,
:func:`temporary_beside`). Output paths are checked before any work
(:func:`check_out_dir`, :func:`check_output_file`, :func:`result_dir`), a
folder is claimed against another run's files (:func:`claim_output`,
:func:`remove_stale`), and data become strict JSON (:func:`jsonable`,
:func:`to_json`, :func:`versions`).

This module owns those mechanics for every writer of the package, and
``symcushion.run.results`` re-exports them. It must not know what a result file
holds (``symcushion.run.results`` writes and reads the trajectory files), and it
must not simulate or plot.
"""
from __future__ import annotations

import json
import os
import platform
import tempfile
from contextlib import contextmanager
from pathlib import Path

import numpy as np

__all__ = ["check_out_dir", "check_output_file", "result_dir", "OutputExists", "claim_output",
           "remove_stale", "temporary_beside", "atomic_write_text", "replacing", "versions",
           "jsonable", "to_json"]


def _file_mode() -> int:
    umask = os.umask(0)
    os.umask(umask)
    return 0o666 & ~umask


#: Permissions of written files: those of open(), 0666 less the umask.
_FILE_MODE = _file_mode()


# ---------------------------------------------------------------------------
# output paths, checked before any work
# ---------------------------------------------------------------------------
def check_out_dir(path, argument: str = "--out") -> Path:
    """Check that ``path`` is, or can be made, a writable directory; create it.

    Called before a run so that a bad output path fails in a second, not after
    the simulation. Rejects a path that is a file, lies under a file, or is in
    a directory that cannot be written.

    Parameters
    ----------
    path : str or Path
    argument : str
        Name of the argument, for the message (``--out``, ``out_dir``).

    Returns
    -------
    Path
        The directory, existing and writable.
    """
    if path is None or str(path) == "":
        raise ValueError(f"`{argument}` must be a directory path, got {path!r}.")
    out = Path(path)
    for parent in [out, *out.parents]:
        if parent.exists() and not parent.is_dir():
            where = "is" if parent == out else f"lies under {parent}, which is"
            raise ValueError(f"`{argument}` {out} {where} a file, not a directory; "
                             "give a directory path.")
    try:
        out.mkdir(parents=True, exist_ok=True)
        fd, probe = tempfile.mkstemp(dir=out, prefix=".write-probe-")
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        raise ValueError(f"`{argument}` {out} cannot be written ({exc.strerror}); give a "
                         "directory you may write to.") from None
    return out


def check_output_file(path, argument: str = "--out") -> Path:
    """Check that a file may be written at ``path`` (its directory is made writable)."""
    if path is None or str(path) == "":
        raise ValueError(f"`{argument}` must be a file path, got {path!r}.")
    path = Path(path)
    if path.is_dir():
        raise ValueError(f"`{argument}` {path} is a directory; give a file path.")
    for parent in path.parents:
        if parent.exists() and not parent.is_dir():
            raise ValueError(f"`{argument}` {path} lies under {parent}, which is a file, not a "
                             "directory; give a path in a directory.")
    check_out_dir(path.parent if str(path.parent) else ".", argument)
    return path


def result_dir(out_dir, name: str, argument: str = "--out") -> Path:
    """The result directory ``out_dir/name``, checked and created.

    ``name`` (the scene's name) must be a plain name: no path separator, not
    ``.`` or ``..``, not absolute, so that a run never writes outside ``out_dir``.
    """
    if not isinstance(name, str) or not name.strip():
        raise ValueError(f"the scene `name` must be a non-empty string, got {name!r}.")
    bad = (os.sep in name or "/" in name or (os.altsep and os.altsep in name)
           or name in (".", "..") or Path(name).is_absolute())
    if bad:
        raise ValueError(f"the scene `name` {name!r} must be a plain file name (no '/', "
                         "'..' or absolute path): results go to OUT/<name>; rename it, "
                         "e.g. name = \"drop_1\".")
    out = check_out_dir(out_dir, argument)
    return check_out_dir(out / name, argument)


class OutputExists(ValueError):
    """The output folder holds results of another run, and ``overwrite`` was not given."""


def claim_output(directory, owned, *, overwrite: bool = False,
                 argument: str = "--out") -> list:
    """Check that ``directory`` holds none of the files a run would write.

    A second run into a folder would replace some of the first run's files
    and leave the others (a figure the second run does not draw) beside
    them, so a folder holding any of ``owned`` is refused unless
    ``overwrite``; the run then removes the stale ones with
    :func:`remove_stale`. Called before any work.

    Parameters
    ----------
    directory : Path
        The output folder (existing: :func:`check_out_dir`).
    owned : sequence of str
        Names of the files (or folders) the run writes there.
    overwrite : bool
        Allow replacing them.
    argument : str
        The output argument, for the message.

    Returns
    -------
    list of Path
        The owned paths that exist.

    Raises
    ------
    OutputExists
        (a ValueError) when some exist and ``overwrite`` is False.
    """
    directory = Path(directory)
    existing = [directory / name for name in owned if (directory / name).exists()]
    if existing and not overwrite:
        names = ", ".join(p.name for p in existing)
        raise OutputExists(f"`{argument}` {directory} already holds the results of another run "
                           f"({names}); give `--overwrite` to replace them (only these names "
                           "are removed), or choose another folder.")
    return existing


def remove_stale(directory, owned, keep=()) -> list:
    """Remove the files of ``owned`` in ``directory`` that are not in ``keep``.

    Only the given names are touched, never another file of the folder; a
    name that is a folder is removed with the files in it.

    Returns
    -------
    list of Path
        What was removed.
    """
    import shutil

    directory = Path(directory)
    keep = {Path(k).name for k in keep}
    removed = []
    for name in owned:
        path = directory / name
        if name in keep or not (path.exists() or path.is_symlink()):
            continue
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path)
        else:
            path.unlink()
        removed.append(path)
    return removed


def temporary_beside(path: Path, mode: str):
    """A temporary file beside ``path`` (same directory: os.replace is atomic there)."""
    # the real suffix last, so that writers that infer a format from it still can
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.",
                               suffix=f".tmp{path.suffix}")
    os.chmod(tmp, _FILE_MODE)       # mkstemp makes 0600; results are ordinary files
    return os.fdopen(fd, mode, **({"newline": ""} if "b" not in mode else {})), Path(tmp)


def atomic_write_text(path, text: str) -> Path:
    """Write ``text`` to ``path`` through a temporary file and :func:`os.replace`."""
    path = Path(path)
    fh, tmp = temporary_beside(path, "w")
    try:
        with fh:
            fh.write(text)
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return path


@contextmanager
def replacing(path):
    """Yield a temporary path beside ``path``; move it onto ``path`` if the block succeeds.

    For writers that take a file name (``savefig``, animation writers): a
    failure or a kill leaves the previous ``path`` or none, never half a file.
    """
    path = Path(path)
    fh, tmp = temporary_beside(path, "wb")
    fh.close()
    try:
        yield tmp
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def versions() -> dict:
    """Versions of symcushion, CasADi, NumPy and Python (for ``run.json``)."""
    import casadi

    from symcushion import __version__

    return {"symcushion": __version__, "casadi": casadi.__version__, "numpy": np.__version__,
            "python": platform.python_version()}


def _json_default(value):
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, (np.floating, np.integer, np.bool_)):
        return value.item()
    return str(value)


def jsonable(v):
    """``v`` with arrays as lists, NumPy scalars as Python numbers and NaN/inf as None."""
    if isinstance(v, dict):
        return {str(k): jsonable(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [jsonable(x) for x in v]
    if isinstance(v, np.ndarray):
        return jsonable(v.tolist())
    if isinstance(v, (float, np.floating)):
        return float(v) if np.isfinite(v) else None
    if isinstance(v, np.integer):
        return int(v)
    return v


def to_json(data) -> str:
    """JSON text of ``data`` (arrays as lists, NaN and inf as null: strict JSON)."""
    return json.dumps(jsonable(data), indent=2, default=_json_default, allow_nan=False)

"""
The output policy: every file or folder an lbscene command writes goes through here.

Rules (the same for every command):

1. **Never replace what lbscene did not make.**  An existing output file is
   replaced only if lbscene wrote it and nobody changed it since: each folder
   that receives outputs keeps a ledger, ``.lbscene-outputs.json``, of the files
   lbscene wrote there and their sha256.  An existing output *folder* (a build)
   is replaced only if it holds lbscene's ``manifest.json`` and nothing the
   manifest does not list (an empty folder is also accepted).  Anything else is
   refused with ``LB611`` and left as it is.
2. **No output is one of the run's inputs**, nor a folder that holds one
   (``LB612``): every file read through :func:`lbscene.engine.files.yamlio.read_bytes_bounded`
   is recorded, and commands declare their command-line inputs.
3. **Outputs named inside a file are confined** to that file's folder (or a
   folder allowed with ``--allow-path``), as file references are (``LB201``).
4. **An unwritable target is a located error** (``LB610``): a folder given for a
   file, a parent that is a file, a read-only or virtual file system — probed by
   creating (and removing) a temporary file where the output will go, before any
   work is done.
5. **Atomic, and self-cleaning.**  Outputs are assembled in temporary siblings
   named ``.<name>.lbtmp-<pid>-<random>`` and moved into place when complete; a
   later run removes the leftovers of runs whose process is gone.

Examples
--------
>>> import tempfile, pathlib
>>> d = pathlib.Path(tempfile.mkdtemp())
>>> p = check_output_file(d / "out.txt", option="--out")
>>> write_output(p, "one")
>>> write_output(p, "two")            # lbscene wrote it: replaced
>>> p.read_text()
'two'
>>> _ = (d / "mine.txt").write_text("user data")
>>> try:
...     check_output_file(d / "mine.txt", option="--out")
... except Exception as exc:
...     print(exc.diagnostics[0].code)
LB611
"""

from __future__ import annotations

import errno
import fcntl
import hashlib
import json
import os
import re
import shutil
import stat
import tempfile
import time
from contextlib import contextmanager
from pathlib import Path
from typing import Iterable, Iterator

from .diagnostics import Diagnostic, LbsceneUserError, SourceLocation

__all__ = [
    "LEDGER_NAME",
    "MANIFEST_NAME",
    "INPUTS",
    "register_input",
    "check_output_file",
    "check_output_dir",
    "check_outputs",
    "output_path",
    "write_output",
    "temporary_dir_for",
    "replace_dir",
    "clean_leftovers",
    "made_by_lbscene",
    "restore_interrupted",
    "fault_point",
]

#: Per-folder ledger of the files lbscene wrote there (name → sha256).
LEDGER_NAME = ".lbscene-outputs.json"
#: The file that marks a folder as an lbscene product (build folders, bake folders).
MANIFEST_NAME = "manifest.json"
#: Bound on the ledger's size (it lists file names and hashes only).
_MAX_LEDGER_BYTES = 4 * 1024 * 1024
#: Leftovers older than this whose writer cannot be identified (old naming) are removed.
_LEGACY_AGE_S = 3600.0

_TMP_RE = re.compile(r"^\.(?P<name>.+)\.(?:lbtmp|lbold)-(?P<pid>\d+)-[A-Za-z0-9_]+(?:\.[A-Za-z0-9]+)?$")
# temporaries of earlier lbscene versions (no pid in the name)
_LEGACY_RE = re.compile(r"^\.(?P<name>.+)\.(?:tmp-[A-Za-z0-9_]{6,}|old-\d+|[A-Za-z0-9_]{8}\.tmp)$")

#: Resolved paths of every input this process has read (see :func:`register_input`).
INPUTS: set[str] = set()


def register_input(path: Path | str) -> None:
    """Record ``path`` as an input of this run: no output may replace it."""
    try:
        INPUTS.add(str(Path(path).resolve()))
    except (OSError, RuntimeError):
        pass


def _err(code: str, message: str, path: Path | str, option: str | None,
         location: SourceLocation | None = None, **kw) -> LbsceneUserError:
    what = f"{option}: " if option else ""
    loc = location or SourceLocation(str(path))
    return LbsceneUserError(Diagnostic(code, what + message, loc, **kw))


def _sha256_file(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


# --------------------------------------------------------------------------- ledger


def _read_ledger(folder: Path) -> dict[str, dict]:
    p = folder / LEDGER_NAME
    try:
        st = p.lstat()
        if not stat.S_ISREG(st.st_mode) or st.st_size > _MAX_LEDGER_BYTES:
            return {}
        d = json.loads(p.read_bytes()[:_MAX_LEDGER_BYTES])
        files = d.get("files") if isinstance(d, dict) else None
        return {k: v for k, v in files.items() if isinstance(v, dict)} if isinstance(files, dict) else {}
    except (OSError, ValueError):
        return {}


@contextmanager
def _folder_lock(folder: Path) -> Iterator[None]:
    """An exclusive lock on ``folder`` (flock on its descriptor) while its ledger is updated."""
    fd = os.open(folder, os.O_RDONLY)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        yield
    finally:
        os.close(fd)


def _record(path: Path, command: str | None = None) -> None:
    """Add ``path`` (just written by lbscene) to its folder's ledger."""
    folder = path.parent
    with _folder_lock(folder):
        files = _read_ledger(folder)
        files[path.name] = {"sha256": _sha256_file(path), "size": path.stat().st_size}
        if command:
            files[path.name]["command"] = command
        text = json.dumps({"about": "files written by lbscene in this folder; an output is replaced "
                                    "only if it is listed here with its current sha256",
                           "files": dict(sorted(files.items()))}, indent=1) + "\n"
        _atomic_write_bytes(folder / LEDGER_NAME, text.encode())


def made_by_lbscene(path: Path) -> bool:
    """True if ``path`` is a file lbscene wrote and nobody changed since (by the folder's ledger)."""
    path = Path(path)
    entry = _read_ledger(path.parent).get(path.name)
    if not entry:
        return False
    try:
        st = path.lstat()
        if not stat.S_ISREG(st.st_mode) or st.st_size != entry.get("size"):
            return False
        return _sha256_file(path) == entry.get("sha256")
    except OSError:
        return False


# --------------------------------------------------------------------------- checks


def _is_input(path: Path) -> str | None:
    """The input that ``path`` is, or holds (for a folder), if any."""
    try:
        rp = str(path.resolve())
    except (OSError, RuntimeError):
        return None
    for inp in INPUTS:
        if inp == rp or inp.startswith(rp.rstrip(os.sep) + os.sep):
            return inp
    if path.exists():
        for inp in INPUTS:
            try:
                if os.path.samefile(inp, path):
                    return inp
            except OSError:
                continue
    return None


def _probe_parent(path: Path, option: str | None, location) -> None:
    """Fail with LB610 unless a file can be created where ``path`` will be."""
    anc = path.parent
    while True:
        try:
            st = anc.stat()
        except FileNotFoundError:
            if anc.parent == anc:
                break
            anc = anc.parent
            continue
        except OSError as exc:
            raise _err("LB610", f"cannot use the folder {str(anc)!r}: {exc.strerror}", path, option,
                       location) from None
        if not stat.S_ISDIR(st.st_mode):
            raise _err("LB610", f"cannot write here: {str(anc)!r} is a file, not a folder", path, option,
                       location, expected="a path whose parents are folders")
        break
    try:
        fd, name = tempfile.mkstemp(prefix=f".lbscene-probe-{os.getpid()}-", dir=anc)
    except OSError as exc:
        raise _err("LB610", f"cannot write in the folder {str(anc)!r}: {exc.strerror}", path, option,
                   location, expected="a writable folder") from None
    os.close(fd)
    os.unlink(name)


def _lstat(path: Path, option, location) -> os.stat_result | None:
    """``lstat`` of an output path (None if it does not exist); LB610 where it cannot be used."""
    try:
        return path.lstat()
    except FileNotFoundError:
        return None
    except NotADirectoryError:
        raise _err("LB610", "cannot write here: a parent of this path is a file, not a folder", path,
                   option, location, expected="a path whose parents are folders") from None
    except OSError as exc:
        raise _err("LB610", f"cannot use this path: {exc.strerror}", path, option, location) from None


def _confine(path: Path, confine_to: Path | None, allowed_dirs: Iterable[Path], option, location) -> None:
    if confine_to is None:
        return
    rp = path.resolve()
    for base in (confine_to, *allowed_dirs):
        try:
            rp.relative_to(Path(base).resolve())
            return
        except ValueError:
            continue
    raise _err("LB201", f"output path escapes the folder of the file that names it ({confine_to})",
               path, option, location, value=str(path),
               expected="a path inside that folder",
               hint="allow another folder with --allow-path")


def check_output_file(path: Path | str, *, option: str | None = None,
                      confine_to: Path | None = None, allowed_dirs: Iterable[Path] = (),
                      location: SourceLocation | None = None) -> Path:
    """Check, before any work, that ``path`` may be written as an output file.

    Parameters
    ----------
    path : the output file.
    option : how the user named it (``"--out"``, ``"output.png"``), for messages.
    confine_to : a folder the output must stay in (outputs named inside a config file).
    allowed_dirs : extra folders allowed with ``--allow-path``.
    location : where it was named (a config's ``file:line:col``), for messages.

    Raises
    ------
    LbsceneUserError
        ``LB610`` not writable, ``LB611`` exists and is not lbscene's, ``LB612`` one of the
        run's inputs, ``LB201`` escapes its config's folder.
    """
    path = Path(path)
    if str(path) in ("", "."):
        raise _err("LB610", "expected a file name, got the current folder", path, option, location)
    _confine(path, confine_to, allowed_dirs, option, location)
    st = _lstat(path, option, location)
    if st is not None and stat.S_ISDIR(st.st_mode):
        raise _err("LB610", "is a folder; expected a file name", path, option, location,
                   expected="a file path")
    inp = _is_input(path)
    if inp is not None:
        raise _err("LB612", "output would replace one of this run's inputs", path, option, location,
                   value=inp, expected="a path that is not an input")
    if st is not None:
        if stat.S_ISLNK(st.st_mode):
            raise _err("LB611", "is a symbolic link; lbscene does not replace links", path, option, location,
                       expected="a new file or one lbscene wrote")
        if not stat.S_ISREG(st.st_mode):
            raise _err("LB611", "exists and is not a regular file", path, option, location,
                       expected="a new file or one lbscene wrote")
        if not made_by_lbscene(path):
            raise _err("LB611", "file exists and was not written by lbscene (or was changed since); "
                                "it is left as it is", path, option, location,
                       expected="a new file or one lbscene wrote",
                       hint="choose another name, or move the file away")
    _probe_parent(path, option, location)
    return path


def _manifest_files(folder: Path) -> set[str] | None:
    """Files a folder's lbscene manifest lists, or None if it has no valid lbscene manifest."""
    m = folder / MANIFEST_NAME
    try:
        st = m.lstat()
        if not stat.S_ISREG(st.st_mode) or st.st_size > 64 * 1024 * 1024:
            return None
        d = json.loads(m.read_bytes())
    except (OSError, ValueError):
        return None
    if not isinstance(d, dict) or not isinstance(d.get("files"), dict):
        return None
    if "lbscene_version" not in d and "job_hash" not in d:
        return None
    return set(d["files"])


def _foreign_files(folder: Path, listed: set[str]) -> list[str]:
    """Files under ``folder`` that its manifest does not list (sub-folders with their own lbscene
    manifest, e.g. bakes, count as lbscene's)."""
    out = []
    for root, dirs, files in os.walk(folder):
        rel_root = Path(root).relative_to(folder)
        keep = []
        for d in dirs:
            sub = Path(root) / d
            if _manifest_files(sub) is not None or _TMP_RE.match(d) or _LEGACY_RE.match(d):
                continue
            keep.append(d)
        dirs[:] = keep
        for f in files:
            rel = (rel_root / f).as_posix()
            if rel in listed or rel == MANIFEST_NAME or f == LEDGER_NAME or _TMP_RE.match(f):
                continue
            out.append(rel)
            if len(out) >= 5:
                return out
    return out


def check_output_dir(path: Path | str, *, option: str | None = None,
                     location: SourceLocation | None = None, owned=None) -> Path:
    """Check, before any work, that the folder ``path`` may be (re)written as an lbscene product.

    Accepted: a path that does not exist, an empty folder, or a folder with lbscene's
    ``manifest.json`` that holds nothing the manifest does not list, or a folder the
    product's own test ``owned(path)`` recognises (e.g. an earlier web export).
    """
    path = Path(path)
    inp = _is_input(path)
    if inp is not None:
        raise _err("LB612", "output folder would replace or hold one of this run's inputs", path, option,
                   location, value=inp, expected="a folder that holds no input")
    st = _lstat(path, option, location)
    if st is not None and str(path.resolve()) == str(Path.cwd().resolve()):
        raise _err("LB610", "the current folder cannot be an output folder", path, option, location,
                   expected="a sub-folder name, e.g. build/<booth>")
    if st is not None:
        if stat.S_ISLNK(st.st_mode):
            raise _err("LB611", "is a symbolic link; lbscene does not replace links", path, option, location)
        if not stat.S_ISDIR(st.st_mode):
            raise _err("LB610", "exists and is not a folder", path, option, location,
                       expected="a folder path")
        try:
            empty = not any(path.iterdir())
        except OSError as exc:
            raise _err("LB610", f"cannot read the folder: {exc.strerror}", path, option, location) from None
        if not empty and not (owned is not None and owned(path)):
            listed = _manifest_files(path)
            if listed is None:
                raise _err("LB611", "folder exists and is not an lbscene output (no lbscene manifest.json); "
                                    "it is left as it is", path, option, location,
                           expected="a new or empty folder, or one lbscene wrote",
                           hint="choose another folder")
            foreign = _foreign_files(path, listed)
            if foreign:
                raise _err("LB611", "folder holds files lbscene did not write; it is left as it is",
                           path, option, location, value=", ".join(foreign),
                           expected="only the files its manifest lists",
                           hint="move those files away or choose another folder")
    _probe_parent(path, option, location)
    return path


# --------------------------------------------------------------------------- writing


def check_outputs(outputs: Iterable[tuple[Path | str | None, str]], *, inputs: Iterable[Path | str] = (),
                  dirs: Iterable[tuple[Path | str | None, str]] = ()) -> None:
    """A command's checks before it starts work: record its command-line ``inputs``, then check
    each ``(path, option)`` output file and output folder (``None`` paths are skipped), and that no
    two outputs are the same path."""
    from .diagnostics import Diagnostic as _D

    for p in inputs:
        if p is not None:
            register_input(p)
    seen: dict[str, str] = {}
    for items, check in ((outputs, check_output_file), (dirs, check_output_dir)):
        for path, option in items:
            if path is None:
                continue
            key = str(Path(path).resolve())
            if key in seen:
                raise LbsceneUserError(_D("LB500", f"{option} and {seen[key]} name the same output",
                                          SourceLocation(str(path)), expected="different paths"))
            seen[key] = option
            check(path, option=option)


def _pid_alive(pid: int) -> bool:
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def clean_leftovers(folder: Path, name: str | None = None) -> list[Path]:
    """Remove temporaries of interrupted lbscene runs in ``folder`` (for outputs called ``name``,
    or all); a temporary is removed only when the process that made it is gone."""
    removed = []
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return removed
    now = time.time()
    for e in entries:
        m = _TMP_RE.match(e.name)
        if m:
            if (name is not None and m["name"] != name) or _pid_alive(int(m["pid"])):
                continue
        else:
            m = _LEGACY_RE.match(e.name)
            if not m or (name is not None and m["name"] != name):
                continue
            try:
                if now - e.stat(follow_symlinks=False).st_mtime < _LEGACY_AGE_S:
                    continue
            except OSError:
                continue
        p = Path(e.path)
        try:
            if e.is_dir(follow_symlinks=False):
                shutil.rmtree(p, ignore_errors=True)
            else:
                p.unlink(missing_ok=True)
            removed.append(p)
        except OSError:
            continue
    return removed


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def _tmp_name(path: Path, kind: str = "lbtmp", suffix: str = "") -> Path:
    tag = os.urandom(4).hex()
    return path.with_name(f".{path.name}.{kind}-{os.getpid()}-{tag}{suffix}")


def _mkdirs(folder: Path, option: str | None = None) -> None:
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise _err("LB610", f"cannot create the folder {str(folder)!r}: {exc.strerror}", folder,
                   option) from None


def _atomic_write_bytes(path: Path, data: bytes) -> None:
    tmp = _tmp_name(path, suffix=".tmp")
    try:
        with open(tmp, "xb") as f:
            f.write(data)
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


@contextmanager
def output_path(path: Path | str, suffix: str = ".tmp", *, option: str | None = None,
                record: bool = True) -> Iterator[Path]:
    """Yield a temporary sibling of ``path`` to write; on success it replaces ``path`` and is
    recorded in the folder's ledger.  On any exception nothing is left behind.

    The caller has checked ``path`` with :func:`check_output_file`; it is checked again here
    against the inputs read since (the bounded reader records them).
    """
    path = Path(path)
    inp = _is_input(path)
    if inp is not None:
        raise _err("LB612", "output would replace one of this run's inputs", path, option,
                   value=inp, expected="a path that is not an input")
    _mkdirs(path.parent, option)
    clean_leftovers(path.parent, path.name)
    tmp = _tmp_name(path, suffix=suffix)
    try:
        try:
            os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600))
        except OSError as exc:
            raise _err("LB610", f"cannot write: {exc.strerror}", path, option) from None
        yield tmp
        os.chmod(tmp, 0o666 & ~_umask())
        try:
            os.replace(tmp, path)
        except OSError as exc:
            if exc.errno in (errno.EISDIR, errno.ENOTDIR, errno.EACCES, errno.EPERM, errno.EROFS):
                raise _err("LB610", f"cannot write: {exc.strerror}", path, option) from None
            raise
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    if record:
        _record(path)


def write_output(path: Path | str, data: bytes | str, *, option: str | None = None) -> None:
    """Write ``data`` (str as UTF-8) to the output file ``path`` atomically (see :func:`output_path`)."""
    raw = data.encode("utf-8") if isinstance(data, str) else data
    try:
        with output_path(path, option=option) as tmp:
            tmp.write_bytes(raw)
    except OSError as exc:
        if exc.errno in (errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EACCES, errno.EPERM, errno.EIO):
            raise _err("LB610", f"cannot write: {exc.strerror}", path, option) from None
        raise


def temporary_dir_for(out_dir: Path | str, *, option: str | None = None) -> Path:
    """A fresh, empty sibling folder of ``out_dir`` to assemble it in (see :func:`replace_dir`);
    leftovers of interrupted runs beside it are removed first."""
    out_dir = Path(out_dir)
    _mkdirs(out_dir.parent, option)
    clean_leftovers(out_dir.parent, out_dir.name)
    tmp = _tmp_name(out_dir)
    try:
        tmp.mkdir()
    except OSError as exc:
        raise _err("LB610", f"cannot write: {exc.strerror}", out_dir, option) from None
    os.chmod(tmp, 0o777 & ~_umask())
    return tmp


def _exchange(a: Path, b: Path) -> bool:
    """Swap two paths atomically (Linux ``renameat2(RENAME_EXCHANGE)``); False where unsupported."""
    import ctypes

    try:
        libc = ctypes.CDLL(None, use_errno=True)
        fn = libc.renameat2
    except (OSError, AttributeError):
        return False
    at_fdcwd, rename_exchange = -100, 2
    rc = fn(at_fdcwd, os.fsencode(str(a)), at_fdcwd, os.fsencode(str(b)), rename_exchange)
    return rc == 0


def fault_point(name: str) -> None:
    """Fault injection for the tests: the process dies here, as under ``kill -9``, when the
    environment variable ``LBSCENE_FAULT`` names this point."""
    if os.environ.get("LBSCENE_FAULT") == name:
        os._exit(70)


def replace_dir(tmp_dir: Path | str, out_dir: Path | str) -> None:
    """Move a finished folder into place, replacing ``out_dir``.

    On Linux the two folders are exchanged in one atomic step, so ``out_dir`` is at every
    moment either the old folder or the new one.  Elsewhere the old folder is first renamed
    to a sibling ``.<name>.lbold-<pid>-…``; if the process dies between the two renames, the
    next run of the same output puts it back (:func:`restore_interrupted`).
    """
    out_dir = Path(out_dir)
    tmp_dir = Path(tmp_dir)
    if out_dir.exists() and _exchange(tmp_dir, out_dir):
        fault_point("replace")
        shutil.rmtree(tmp_dir, ignore_errors=True)        # holds the old folder now
        return
    old = None
    if out_dir.exists():
        old = _tmp_name(out_dir, kind="lbold")
        os.replace(out_dir, old)
        fault_point("replace")
    os.replace(tmp_dir, out_dir)
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)


def restore_interrupted(out_dir: Path) -> None:
    """If an interrupted :func:`replace_dir` left ``out_dir`` missing and its old copy aside, put
    the old copy back (called before a new run of the same output)."""
    out_dir = Path(out_dir)
    if out_dir.exists():
        return
    try:
        entries = list(os.scandir(out_dir.parent))
    except OSError:
        return
    for e in entries:
        m = _TMP_RE.match(e.name)
        if m and m["name"] == out_dir.name and ".lbold-" in e.name and not _pid_alive(int(m["pid"])):
            try:
                os.replace(e.path, out_dir)
            except OSError:
                pass
            return


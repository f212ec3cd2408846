"""
The output policy: every file or folder an lbscene command writes goes through here.

Rules (the same for every command):

1. **Never replace what lbscene did not make.**  An existing output file is
   replaced only if lbscene wrote it and nobody changed it since: each folder
   that receives outputs keeps a ledger, ``.lbscene-outputs.json``, of the files
   lbscene wrote there and their sha256.  A ledger is believed only if it is a
   regular file of the current user, and only for files that still match its
   sha256, are not newer than the ledger, belong to the current user and are
   not read-only.  An existing output *folder* (a build, a bake, a web export)
   is replaced only if every file in it, recursively, is one lbscene made and
   unchanged: listed with its sha256 by a ``manifest.json`` of lbscene in that
   folder or above it, or by a ledger (sub-folders are never exempt).  Anything
   else is refused with ``LB611`` and left as it is.
2. **No output is one of the run's inputs**, nor a folder that holds one
   (``LB612``): every file read through :func:`lbscene.engine.files.yamlio.read_bytes_bounded`
   is recorded, and commands declare their command-line inputs.
3. **Outputs named inside a file are confined** to that file's folder (or a
   folder allowed with ``--allow-path``), as file references are (``LB201``).
4. **An unwritable target is a located error** (``LB610``): a folder given for a
   file, a parent that is a file, a read-only or virtual file system — probed by
   creating (and removing) a temporary file where the output will go, before any
   work is done; a full disk while writing (nothing is changed then).
5. **Ownership is checked again at the moment of writing.**  Files are created
   exclusively (``O_CREAT | O_EXCL | O_NOFOLLOW``) and written through the
   descriptor that created them; a writer that needs a path (matplotlib, OpenEXR,
   ``np.save``) gets one inside a private ``0700`` folder made beside the target.
   The result is moved into place with ``renameat2(RENAME_NOREPLACE)`` (a file
   that appeared meanwhile is never clobbered) or, over lbscene's own earlier
   output, exchanged with it (``RENAME_EXCHANGE``) and the old file checked once
   more after the exchange, which is undone if it is not lbscene's.  Folders are
   swapped the same way, their old contents checked again after the swap.
6. **Atomic, and self-cleaning.**  Outputs are assembled in temporary siblings
   named ``.<name>.lbtmp-<pid>-<start>-<random>``; a later run removes those of
   this naming whose process is gone (``<start>`` identifies the process beyond
   its pid, so a reused pid does not keep a leftover alive), owned by the current
   user — never a name of any other pattern.

Where ``renameat2`` is missing (not Linux, or a file system without it) a file is
moved with ``link`` + ``unlink`` (no clobbering either) and an existing output is
checked again immediately before ``os.replace``: a file that appears in the
microseconds between that check and the replace is then lost; the same holds
for a folder.  A process killed with SIGKILL between swapping a folder and
removing the old copy leaves the old copy as a leftover, which the next run
removes (it had been checked just before the swap).

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
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Iterable, Iterator

from .diagnostics import Diagnostic, LbsceneUserError, SourceLocation
from .processes import deferred_signals

__all__ = [
    "LEDGER_NAME",
    "MANIFEST_NAME",
    "INPUTS",
    "NO_SPACE_ERRNOS",
    "register_input",
    "check_output_file",
    "check_output_dir",
    "check_outputs",
    "output_path",
    "write_output",
    "write_new_file",
    "temporary_dir_for",
    "temporary_name",
    "replace_dir",
    "commit_file",
    "carry_over",
    "scan_tree",
    "verify_tree",
    "read_manifest",
    "clean_leftovers",
    "made_by_lbscene",
    "no_space_error",
    "process_token",
    "owner_gone",
    "restore_interrupted",
    "fault_point",
]

#: Per-folder ledger of the files lbscene wrote there (name → sha256).
LEDGER_NAME = ".lbscene-outputs.json"
#: The file that marks a folder as an lbscene product (build folders, bake folders, web exports).
MANIFEST_NAME = "manifest.json"
#: Bound on the ledger's size (it lists file names and hashes only).
_MAX_LEDGER_BYTES = 4 * 1024 * 1024
#: Bound on a manifest's size.
_MAX_MANIFEST_BYTES = 64 * 1024 * 1024
#: Folders deeper than this inside an output folder are not lbscene's (and are not descended into).
_MAX_DEPTH = 32
#: ``errno`` values of a full disk or an exhausted quota.
#: a full disk, a quota, or a file larger than the file system or the process may write (EFBIG)
NO_SPACE_ERRNOS = (errno.ENOSPC, errno.EDQUOT, errno.EFBIG)

#: lbscene's temporaries: ``.<name>.lbtmp-<pid>-<start token>-<random><suffix>`` (and ``lbold``, the old
#: copy of a folder being replaced where folders cannot be exchanged); ``<start token>`` is absent in
#: names written by earlier versions and on systems without ``/proc``.
_TMP_RE = re.compile(r"^\.(?P<name>.+)\.(?P<kind>lbtmp|lbold)-(?P<pid>[0-9]{1,10})-(?:(?P<tok>[0-9a-f]{8})-)?"
                     r"(?P<rand>[A-Za-z0-9_]{6,16})(?P<suffix>\.[A-Za-z0-9]{1,10})?$")

_RENAME_NOREPLACE = 1
_RENAME_EXCHANGE = 2
_O_NOFOLLOW_READ = os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_CLOEXEC
_O_DIR = os.O_RDONLY | os.O_DIRECTORY | os.O_CLOEXEC
_O_CREATE = os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW | os.O_CLOEXEC

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


def no_space_error(path: Path | str, option: str | None, exc: OSError,
                   location: SourceLocation | None = None) -> LbsceneUserError:
    """``LB610`` for a write that failed on a full disk (``exc.errno`` in :data:`NO_SPACE_ERRNOS`),
    after the caller removed its temporaries and left the output as it was."""
    return _err("LB610", f"cannot write: {exc.strerror or os.strerror(exc.errno)} (nothing was changed; "
                         "temporary files were removed)", path, option, location)


# --------------------------------------------------------------------------- processes


_BOOT_ID: bytes | None = None
_TOKENS: dict[int, str | None] = {}


def _boot_id() -> bytes:
    global _BOOT_ID
    if _BOOT_ID is None:
        try:
            with open("/proc/sys/kernel/random/boot_id", "rb") as f:
                _BOOT_ID = f.read(64).strip()
        except OSError:
            _BOOT_ID = b""
    return _BOOT_ID


def process_token(pid: int) -> str | None:
    """Eight hex digits naming one run of process ``pid``: a hash of the boot id and the process's
    start time (``/proc/<pid>/stat``, field 22), so a pid reused later, or after a reboot, gets
    another token.  None where it cannot be read (no ``/proc``, no such process).

    Examples
    --------
    >>> import os
    >>> process_token(os.getpid()) == process_token(os.getpid())
    True
    """
    try:
        with open(f"/proc/{int(pid)}/stat", "rb") as f:
            data = f.read(4096)
        start = data[data.rindex(b")") + 2:].split()[19]
    except (OSError, ValueError, IndexError):
        return None
    return hashlib.blake2b(_boot_id() + b"/" + start, digest_size=4).hexdigest()


def _my_token() -> str | None:
    pid = os.getpid()
    if pid not in _TOKENS:
        _TOKENS[pid] = process_token(pid)
    return _TOKENS[pid]


def owner_gone(pid: int, token: str | None) -> bool:
    """Whether the process that named a temporary ``(pid, token)`` has ended.

    A pid that is alive but now belongs to another process (another start token) counts as
    ended; where the token cannot be checked, a live pid counts as the owner (the temporary is
    kept: when in doubt, nothing is removed).
    """
    if pid <= 1:
        return False
    if pid == os.getpid():
        mine = _my_token()
        return token is not None and mine is not None and token != mine
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    except PermissionError:
        pass
    except (OverflowError, OSError):
        return False
    if token is None:
        return False
    now = process_token(pid)
    return now is not None and now != token


def _tmp_prefix(path: Path, kind: str = "lbtmp") -> str:
    tok = _my_token()
    return f".{path.name}.{kind}-{os.getpid()}-" + (f"{tok}-" if tok else "")


def _tmp_name(path: Path, kind: str = "lbtmp", suffix: str = "") -> Path:
    return path.with_name(_tmp_prefix(path, kind) + os.urandom(4).hex() + suffix)


def temporary_name(path: Path | str, suffix: str = "") -> Path:
    """A name for a temporary sibling of ``path`` in lbscene's own pattern (removed by a later
    run once this process is gone, see :func:`clean_leftovers`); nothing is created."""
    return _tmp_name(Path(path), suffix=suffix)


def _leftover_removable(dir_fd: int, m: re.Match, st: os.stat_result) -> bool:
    """An entry of lbscene's temporary pattern (``m``) in the folder ``dir_fd`` that may go: the
    current user's, its process gone, and (for the old copy of a folder) not needed to restore
    that folder."""
    if st.st_uid != os.geteuid() or not owner_gone(int(m["pid"]), m["tok"]):
        return False
    if m["kind"] == "lbold":
        try:
            os.stat(m["name"], dir_fd=dir_fd, follow_symlinks=False)
        except OSError:
            return False                  # the folder it was the old copy of is missing: restore, not remove
    return True


def _remove_entry(name: str, dir_fd: int, is_dir: bool) -> None:
    if is_dir:
        shutil.rmtree(name, dir_fd=dir_fd, ignore_errors=True)
    else:
        try:
            os.unlink(name, dir_fd=dir_fd)
        except OSError:
            pass


def clean_leftovers(folder: Path, name: str | None = None) -> list[Path]:
    """Remove temporaries of interrupted lbscene runs in ``folder`` (for outputs called ``name``,
    or all).

    Only entries named in lbscene's own pattern ``.<name>.lbtmp-<pid>-…`` are considered, and
    one is removed only when it belongs to the current user and the process that made it is
    gone (:func:`owner_gone`).  A file or folder of any other name is never touched.
    """
    removed: list[Path] = []
    try:
        fd = os.open(folder, _O_DIR)
    except OSError:
        return removed
    try:
        for e in list(os.scandir(fd)):
            m = _TMP_RE.match(e.name)
            if not m or (name is not None and m["name"] != name):
                continue
            try:
                st = e.stat(follow_symlinks=False)
            except OSError:
                continue
            if not _leftover_removable(fd, m, st):
                continue
            _remove_entry(e.name, fd, stat.S_ISDIR(st.st_mode))
            removed.append(Path(folder) / e.name)
    except OSError:
        pass
    finally:
        os.close(fd)
    return removed


# --------------------------------------------------------------------------- reading what lbscene wrote


_HASHED: dict[tuple, str] = {}


def _sha_fd(fd: int, st: os.stat_result) -> str:
    """sha256 of an open regular file, remembered by its identity (inode, size, mtime, ctime: any
    write or ``chmod`` changes the ctime, so a remembered hash is never stale)."""
    key = (st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns, st.st_ctime_ns)
    got = _HASHED.get(key)
    if got is not None:
        return got
    h = hashlib.sha256()
    os.lseek(fd, 0, os.SEEK_SET)
    while True:
        chunk = os.read(fd, 1 << 20)
        if not chunk:
            break
        h.update(chunk)
    if len(_HASHED) > 100_000:
        _HASHED.clear()
    _HASHED[key] = h.hexdigest()
    return _HASHED[key]


def _load_json_owned(name: str | Path, dir_fd: int | None, limit: int) -> tuple[dict, int] | None:
    """A JSON object from a regular file (not a link) of the current user, with its mtime (ns);
    None for anything else.  Never blocks (a FIFO is not opened for reading)."""
    try:
        fd = os.open(name, _O_NOFOLLOW_READ, dir_fd=dir_fd)
    except OSError:
        return None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode) or st.st_uid != os.geteuid() or st.st_size > limit:
            return None
        chunks, n = [], 0
        while n <= limit:
            chunk = os.read(fd, 1 << 20)
            if not chunk:
                break
            chunks.append(chunk)
            n += len(chunk)
        if n > limit:
            return None
        d = json.loads(b"".join(chunks))
        return (d, st.st_mtime_ns) if isinstance(d, dict) else None
    except (OSError, ValueError, RecursionError):   # a ledger nested past the parser: not believed
        return None
    finally:
        os.close(fd)


def _read_ledger(folder: Path | None, dir_fd: int | None = None) -> tuple[dict[str, dict], int | None]:
    """The files a folder's ledger vouches for (name → entry) and the ledger's mtime; empty when
    there is no ledger or it is not believed (not a regular file of the current user)."""
    got = _load_json_owned(LEDGER_NAME if dir_fd is not None else Path(folder) / LEDGER_NAME, dir_fd,
                           _MAX_LEDGER_BYTES)
    if got is None:
        return {}, None
    d, mtime_ns = got
    files = d.get("files")
    if not isinstance(files, dict):
        return {}, None
    return {k: v for k, v in files.items() if isinstance(k, str) and isinstance(v, dict)}, mtime_ns


def read_manifest(folder: Path | str | None, dir_fd: int | None = None) -> tuple[dict, int] | None:
    """An lbscene manifest of ``folder`` (``manifest.json`` with ``files`` and ``lbscene_version``
    or ``job_hash``) and its mtime in ns; None if there is none, or it is not a regular file of
    the current user."""
    got = _load_json_owned(MANIFEST_NAME if dir_fd is not None else Path(folder) / MANIFEST_NAME, dir_fd,
                           _MAX_MANIFEST_BYTES)
    if got is None:
        return None
    d, mtime_ns = got
    if not isinstance(d.get("files"), dict) or ("lbscene_version" not in d and "job_hash" not in d):
        return None
    return d, mtime_ns


def _mismatch(name: str | Path, dir_fd: int | None, sha256: object, size: object = None,
              not_after_ns: int | None = None) -> str | None:
    """Why the file ``name`` is not (or no longer) the one a ledger or manifest recorded — None
    when it is: a regular file of the current user, writable by them, not newer than the
    record, of the recorded size and sha256."""
    if not isinstance(sha256, str):
        return "not recorded"
    try:
        fd = os.open(name, _O_NOFOLLOW_READ, dir_fd=dir_fd)
    except OSError as exc:
        return "a symbolic link" if exc.errno == errno.ELOOP else "unreadable"
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            return "not a regular file"
        if st.st_uid != os.geteuid():
            return "another user's"
        if not st.st_mode & stat.S_IWUSR:
            return "read-only"
        if not_after_ns is not None and st.st_mtime_ns > not_after_ns:
            return "changed"
        if isinstance(size, int) and size != st.st_size:
            return "changed"
        return None if _sha_fd(fd, st) == sha256 else "changed"
    except OSError:
        return "unreadable"
    finally:
        os.close(fd)


def made_by_lbscene(path: Path) -> bool:
    """True if ``path`` is a file lbscene wrote and nobody changed since (by the folder's ledger,
    see the rules of this module)."""
    path = Path(path)
    files, mtime_ns = _read_ledger(path.parent)
    entry = files.get(path.name)
    if not entry:
        return False
    return _mismatch(path, None, entry.get("sha256"), entry.get("size"), mtime_ns) is None


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
    clean_leftovers(anc, "lbscene-probe")
    probe = _tmp_name(anc / "lbscene-probe")
    try:
        fd = os.open(probe, _O_CREATE, 0o600)
    except OSError as exc:
        raise _err("LB610", f"cannot write in the folder {str(anc)!r}: {exc.strerror}", path, option,
                   location, expected="a writable folder") from None
    os.close(fd)
    os.unlink(probe)


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


def _refuse_existing_file(path: Path, option, location) -> None:
    """LB611 unless the existing file ``path`` is one lbscene wrote, unchanged."""
    files, mtime_ns = _read_ledger(path.parent)
    entry = files.get(path.name)
    why = _mismatch(path, None, entry.get("sha256"), entry.get("size"), mtime_ns) if entry else "not recorded"
    if why is None:
        return
    if why == "read-only":
        raise _err("LB611", "file is read-only; lbscene does not replace it", path, option, location,
                   expected="a new file or one lbscene wrote", hint="choose another name, or move the file away")
    raise _err("LB611", "file exists and was not written by lbscene (or was changed since); "
                        "it is left as it is", path, option, location,
               expected="a new file or one lbscene wrote",
               hint="choose another name, or move the file away")


def check_output_file(path: Path | str, *, option: str | None = None,
                      confine_to: Path | None = None, allowed_dirs: Iterable[Path] = (),
                      location: SourceLocation | None = None) -> Path:
    """Check, before any work, that ``path`` may be written as an output file.

    The same check runs again when the file is written (:func:`write_output`,
    :func:`output_path`): a file that appears or changes in between is not replaced.

    Parameters
    ----------
    path : Path or str
        The output file.
    option : str, optional
        How the user named it (``"--out"``, ``"output.png"``), for messages.
    confine_to : Path, optional
        A folder the output must stay in (outputs named inside a config file).
    allowed_dirs : iterable of Path
        Extra folders allowed with ``--allow-path``.
    location : SourceLocation, optional
        Where it was named (a config's ``file:line:col``), for messages.

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    LbsceneUserError
        ``LB610`` not writable, ``LB611`` exists and is not lbscene's (or is read-only),
        ``LB612`` one of the run's inputs, ``LB201`` escapes its config's folder.
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
        _refuse_existing_file(path, option, location)
    _probe_parent(path, option, location)
    return path


# --------------------------------------------------------------------------- folders: every file, recursively


@dataclass
class TreeScan:
    """What :func:`scan_tree` found in a folder (paths relative to it, ``/``-separated).

    Attributes
    ----------
    entries : int
        Entries at the top of the folder, leftovers of gone runs not counted.
    has_manifest : bool
        The folder has an lbscene ``manifest.json`` of its own.
    foreign : list of str
        Files no manifest or ledger vouches for, links, FIFOs, devices.
    changed : list of str
        Files a manifest or ledger lists that differ from what it recorded.
    busy : list of str
        Temporaries of lbscene runs still going (or of another user).
    carried : list of str
        Files vouched for by something other than the folder's own manifest (a bake's
        manifest in a sub-folder, a ledger), and those manifests and ledgers: what a new
        version of the folder takes over (:func:`carry_over`).
    """

    entries: int = 0
    has_manifest: bool = False
    foreign: list[str] = field(default_factory=list)
    changed: list[str] = field(default_factory=list)
    busy: list[str] = field(default_factory=list)
    carried: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return not (self.foreign or self.changed or self.busy)


def _scan_dir(fd: int, parts: tuple[str, ...], manifests: list, out: TreeScan, limit: int) -> None:
    got = read_manifest(None, dir_fd=fd)
    if got is not None:
        d, mtime_ns = got
        manifests = manifests + [(parts, {k: v for k, v in d["files"].items() if isinstance(k, str)}, mtime_ns)]
        if not parts:
            out.has_manifest = True
    ledger, ledger_mtime = _read_ledger(None, dir_fd=fd)
    ledger_ok = ledger_mtime is not None
    for e in sorted(os.scandir(fd), key=lambda e: e.name):
        if len(out.foreign) + len(out.changed) + len(out.busy) >= limit:
            return
        rel = "/".join(parts + (e.name,))
        try:
            st = e.stat(follow_symlinks=False)
        except OSError:
            out.foreign.append(rel)
            continue
        m = _TMP_RE.match(e.name)
        if m:
            if _leftover_removable(fd, m, st):
                _remove_entry(e.name, fd, stat.S_ISDIR(st.st_mode))
            else:
                out.busy.append(rel)
            continue
        if not parts:
            out.entries += 1
        if stat.S_ISDIR(st.st_mode):
            if len(parts) >= _MAX_DEPTH:         # no lbscene product is this deep
                out.foreign.append(rel + "/…")
                continue
            try:
                sub = os.open(e.name, _O_DIR | os.O_NOFOLLOW, dir_fd=fd)
            except OSError:
                out.foreign.append(rel)
                continue
            try:
                _scan_dir(sub, parts + (e.name,), manifests, out, limit)
            finally:
                os.close(sub)
            continue
        if not stat.S_ISREG(st.st_mode):
            out.foreign.append(rel)
            continue
        if e.name == MANIFEST_NAME and got is not None:
            if parts:
                out.carried.append(rel)
            continue
        if e.name == LEDGER_NAME and ledger_ok:
            out.carried.append(rel)
            continue
        why, owner = "not recorded", None
        for prefix, files, mtime_ns in reversed(manifests):
            key = "/".join(parts[len(prefix):] + (e.name,))
            if key in files:
                why, owner = _mismatch(e.name, fd, files[key], None, mtime_ns), prefix
                break
        if owner is None and e.name in ledger:
            entry = ledger[e.name]
            why, owner = _mismatch(e.name, fd, entry.get("sha256"), entry.get("size"), ledger_mtime), "ledger"
        if owner is None:
            out.foreign.append(rel)
        elif why is not None:
            out.changed.append(rel)
        elif owner != ():
            out.carried.append(rel)


def scan_tree(folder: Path | str, *, limit: int = 5) -> TreeScan:
    """Look at every file under ``folder``: which of them lbscene made and nobody changed.

    A file is lbscene's when the nearest ``manifest.json`` of lbscene above it (in the folder
    or a sub-folder) lists it, or else the ledger of its own folder does, and it still matches
    that record (:func:`made_by_lbscene`'s rules).  Sub-folders are never exempt.  Temporaries
    of lbscene runs that are gone are removed on the way (:func:`clean_leftovers`'s rule); those
    of live runs make the folder busy.  The scan stops after ``limit`` problems.

    Raises
    ------
    OSError
        ``folder`` cannot be opened as a folder (it is a link, a file, unreadable).
    """
    fd = os.open(folder, _O_DIR | os.O_NOFOLLOW)
    try:
        out = TreeScan()
        _scan_dir(fd, (), [], out, limit)
        return out
    finally:
        os.close(fd)


def verify_tree(folder: Path | str, *, option: str | None = None, location: SourceLocation | None = None,
                shown: Path | str | None = None) -> TreeScan:
    """Raise ``LB611`` unless every file under ``folder`` is one lbscene made and unchanged
    (:func:`scan_tree`); an empty folder passes.

    Parameters
    ----------
    folder : Path or str
        The folder to check.
    option, location : optional
        How and where the user named it, for messages.
    shown : Path or str, optional
        The path to show in messages (the folder's place as the user knows it, when ``folder``
        is its temporary name after a swap).

    Returns
    -------
    TreeScan
        What was found (for :func:`carry_over`).
    """
    shown = Path(shown if shown is not None else folder)
    try:
        scan = scan_tree(folder)
    except OSError as exc:
        raise _err("LB610", f"cannot read the folder: {exc.strerror}", shown, option, location) from None
    if scan.busy:
        raise _err("LB611", "folder is being written by another lbscene run; it is left as it is", shown,
                   option, location, value=", ".join(scan.busy), expected="no lbscene run writing into it")
    if scan.foreign and not scan.has_manifest:
        raise _err("LB611", "folder exists and is not an lbscene output (no lbscene manifest.json); "
                            "it is left as it is", shown, option, location,
                   expected="a new or empty folder, or one lbscene wrote",
                   hint="choose another folder")
    if scan.foreign:
        raise _err("LB611", "folder holds files lbscene did not write; it is left as it is",
                   shown, option, location, value=", ".join(scan.foreign),
                   expected="only the files its manifest lists",
                   hint="move those files away or choose another folder")
    if scan.changed:
        what = f"{option}: " if option else ""
        raise LbsceneUserError([Diagnostic(
            "LB611", what + "this file was changed since lbscene wrote it; the output folder is left as it is",
            SourceLocation(str(shown / rel)), expected="the file as lbscene wrote it",
            hint="move your edited copy out of the folder, or choose another folder") for rel in scan.changed])
    return scan


def check_output_dir(path: Path | str, *, option: str | None = None,
                     location: SourceLocation | None = None) -> Path:
    """Check, before any work, that the folder ``path`` may be (re)written as an lbscene product.

    Accepted: a path that does not exist, an empty folder, or a folder in which every file,
    recursively, is one lbscene made and unchanged (:func:`verify_tree`).  The same check runs
    again when the new folder is swapped in (:func:`replace_dir`).

    Raises
    ------
    LbsceneUserError
        ``LB610`` not a usable folder, ``LB611`` holds something lbscene did not make (or
        changed), ``LB612`` holds one of the run's inputs.
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
        verify_tree(path, option=option, location=location)
    _probe_parent(path, option, location)
    return path


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


# --------------------------------------------------------------------------- moving into place


_RENAMEAT2: list = []


def _renameat2(src_fd: int, src: str, dst_fd: int, dst: str, flags: int) -> bool:
    """``renameat2`` (Linux); True when done, False where the call or the flag is not supported
    (no such function, or a file system without it).  Other failures raise ``OSError``
    (``FileExistsError`` when ``RENAME_NOREPLACE`` finds ``dst``)."""
    import ctypes

    if not _RENAMEAT2:
        try:
            fn = ctypes.CDLL(None, use_errno=True).renameat2
            fn.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_uint]
            fn.restype = ctypes.c_int
            _RENAMEAT2.append(fn)
        except (OSError, AttributeError):
            _RENAMEAT2.append(None)
    fn = _RENAMEAT2[0]
    if fn is None:
        return False
    if fn(src_fd, os.fsencode(src), dst_fd, os.fsencode(dst), flags) == 0:
        return True
    e = ctypes.get_errno()
    if e in (errno.ENOSYS, errno.EINVAL, errno.ENOTSUP, errno.EOPNOTSUPP):
        return False
    raise OSError(e, os.strerror(e), dst)


def _appeared(shown: Path, option, location) -> LbsceneUserError:
    return _err("LB611", "file appeared or changed while this command ran; it is left as it is and the new "
                         "output was not written", shown, option, location)


def commit_file(src_fd: int, src: str, dst_fd: int, dst: str, *, shown: Path | str,
                may_replace: Callable[[int, str], bool], option: str | None = None,
                location: SourceLocation | None = None) -> None:
    """Move the finished file ``src`` (in folder ``src_fd``) to ``dst`` (in folder ``dst_fd``, same
    file system), never clobbering what lbscene may not replace.

    A new name is taken with ``RENAME_NOREPLACE`` (or ``link`` + ``unlink``): a file that appeared
    meanwhile stays.  An existing ``dst`` is replaced only if ``may_replace(dst_fd, dst)``; it is
    then exchanged with ``src`` (``RENAME_EXCHANGE``) and checked once more where it now lies,
    and put back if the check fails; where exchanging is not supported, it is replaced right after
    the check (the one remaining window, microseconds long).

    Parameters
    ----------
    src_fd, src : int, str
        Folder descriptor and name of the finished temporary.
    dst_fd, dst : int, str
        Folder descriptor and name of the target.
    shown : Path or str
        The target's path, for messages.
    may_replace : callable
        ``(dir_fd, name) -> bool``: whether the file found there may be replaced.
    option, location : optional
        How and where the user named the output, for messages.

    Raises
    ------
    LbsceneUserError
        ``LB611`` when ``dst`` exists and may not be replaced.
    """
    with deferred_signals():        # a signal must not leave a displaced file at a temporary's name
        _commit_file(src_fd, src, dst_fd, dst, Path(shown), may_replace, option, location)


def _commit_file(src_fd, src, dst_fd, dst, shown, may_replace, option, location) -> None:
    try:
        if _renameat2(src_fd, src, dst_fd, dst, _RENAME_NOREPLACE):
            return
        try:
            os.link(src, dst, src_dir_fd=src_fd, dst_dir_fd=dst_fd, follow_symlinks=False)
            os.unlink(src, dir_fd=src_fd)
            return
        except FileExistsError:
            pass
        except OSError as exc:
            if exc.errno not in (errno.EPERM, errno.ENOTSUP, errno.EOPNOTSUPP, errno.EMLINK, errno.EXDEV):
                raise
            try:
                os.stat(dst, dir_fd=dst_fd, follow_symlinks=False)
            except FileNotFoundError:
                os.rename(src, dst, src_dir_fd=src_fd, dst_dir_fd=dst_fd)   # no hard links here
                return
    except FileExistsError:
        pass
    if not may_replace(dst_fd, dst):
        raise _appeared(shown, option, location)
    if _renameat2(src_fd, src, dst_fd, dst, _RENAME_EXCHANGE):
        if may_replace(src_fd, src):                    # the file we displaced, checked where it lies now
            os.unlink(src, dir_fd=src_fd)
            return
        _renameat2(src_fd, src, dst_fd, dst, _RENAME_EXCHANGE)               # put it back
        raise _appeared(shown, option, location)
    os.replace(src, dst, src_dir_fd=src_fd, dst_dir_fd=dst_fd)


def _ledger_may_replace(name: str, ledger_fd: int) -> Callable[[int, str], bool]:
    """``may_replace`` for an output recorded under ``name`` in the ledger of the folder
    ``ledger_fd`` (the target's folder, wherever the file being checked lies: after an exchange
    the displaced file is checked at the temporary's place)."""

    def check(dir_fd: int, at: str) -> bool:
        files, mtime_ns = _read_ledger(None, dir_fd=ledger_fd)
        entry = files.get(name)
        return bool(entry) and _mismatch(at, dir_fd, entry.get("sha256"), entry.get("size"), mtime_ns) is None

    return check


def _own_regular_file(dir_fd: int, name: str) -> bool:
    try:
        st = os.stat(name, dir_fd=dir_fd, follow_symlinks=False)
    except OSError:
        return False
    return stat.S_ISREG(st.st_mode) and st.st_uid == os.geteuid()


def _write_all(fd: int, data: bytes | memoryview) -> None:
    view = memoryview(data)
    while view:
        n = os.write(fd, view)
        view = view[n:]


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def write_via_temporary(dir_fd: int, path: Path, write: "bytes | Callable[[int], None]", *,
                        may_replace: Callable[[int, str], bool], suffix: str = ".tmp",
                        option: str | None = None, location: SourceLocation | None = None) -> os.stat_result:
    """Write ``path`` (its name in the folder ``dir_fd``) through an exclusively created temporary
    beside it: ``write`` is the bytes, or a function given the temporary's descriptor; the file is
    made readable as the umask allows, then moved in by :func:`commit_file` (``may_replace``
    decides over an existing file).  The temporary is removed whatever happens.  Returns the
    written file's ``fstat``."""
    tmp = _tmp_name(path, suffix=suffix).name
    fd = os.open(tmp, _O_CREATE, 0o600, dir_fd=dir_fd)
    try:
        try:
            if callable(write):
                write(fd)
            else:
                _write_all(fd, write)
            os.fchmod(fd, 0o666 & ~_umask())
            st = os.fstat(fd)
        finally:
            os.close(fd)
        commit_file(dir_fd, tmp, dir_fd, path.name, shown=path, may_replace=may_replace, option=option,
                    location=location)
        return st
    finally:
        try:
            os.unlink(tmp, dir_fd=dir_fd)
        except FileNotFoundError:
            pass


def _mkdirs(folder: Path, option: str | None = None) -> None:
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise _err("LB610", f"cannot create the folder {str(folder)!r}: {exc.strerror}", folder,
                   option) from None


@contextmanager
def _dir_fd(folder: Path) -> Iterator[int]:
    fd = os.open(folder, _O_DIR)
    try:
        yield fd
    finally:
        os.close(fd)


@contextmanager
def _folder_lock(folder: Path) -> Iterator[int]:
    """An exclusive lock on ``folder`` (flock on its descriptor) while its ledger is updated."""
    with _dir_fd(folder) as fd:
        fcntl.flock(fd, fcntl.LOCK_EX)
        yield fd


def _is_own_ledger(dir_fd: int, name: str) -> bool:
    return _load_json_owned(name, dir_fd, _MAX_LEDGER_BYTES) is not None


def _record(path: Path, sha256: str, size: int, command: str | None = None) -> None:
    """Add ``path`` (just written by lbscene, with this sha256 and size) to its folder's ledger.

    A ledger that lbscene cannot believe (another user's, not a regular file) is not replaced:
    the output is then not recorded, and a later run will not replace it.
    """
    folder = path.parent
    clean_leftovers(folder, LEDGER_NAME)
    with _folder_lock(folder) as fd:
        try:
            st = os.stat(LEDGER_NAME, dir_fd=fd, follow_symlinks=False)
        except FileNotFoundError:
            st = None
        if st is not None and not _is_own_ledger(fd, LEDGER_NAME):
            return
        files, _ = _read_ledger(None, dir_fd=fd)
        files[path.name] = {"sha256": sha256, "size": size}
        if command:
            files[path.name]["command"] = command
        text = json.dumps({"about": "files written by lbscene in this folder; an output is replaced "
                                    "only if it is listed here with its current sha256",
                           "files": dict(sorted(files.items()))}, indent=1) + "\n"
        try:
            write_via_temporary(fd, folder / LEDGER_NAME, text.encode(), may_replace=_is_own_ledger)
        except LbsceneUserError:
            pass                                     # someone else's file took the ledger's name


# --------------------------------------------------------------------------- writing files


def _check_not_input(path: Path, option, location) -> None:
    inp = _is_input(path)
    if inp is not None:
        raise _err("LB612", "output would replace one of this run's inputs", path, option, location,
                   value=inp, expected="a path that is not an input")


def _write_error(exc: OSError, path: Path, option, location) -> LbsceneUserError | None:
    if exc.errno in NO_SPACE_ERRNOS:
        return no_space_error(path, option, exc, location)
    if exc.errno in (errno.EROFS, errno.EACCES, errno.EPERM, errno.EIO, errno.EISDIR, errno.ENOTDIR):
        return _err("LB610", f"cannot write: {exc.strerror}", path, option, location)
    return None


def write_new_file(path: Path | str, data: bytes | str) -> str:
    """Create the file ``path`` (it must not exist: ``O_EXCL``, links not followed) and write
    ``data`` (str as UTF-8) through the descriptor that created it; returns its sha256.

    For files inside a folder lbscene is assembling (a build, an export); on failure (a full
    disk) the partial file is removed and the ``OSError`` raised.
    """
    raw = data.encode("utf-8") if isinstance(data, str) else bytes(data)
    path = Path(path)
    fd = os.open(path, _O_CREATE, 0o666)
    try:
        _write_all(fd, raw)
    except BaseException:
        os.close(fd)
        path.unlink(missing_ok=True)
        raise
    os.close(fd)
    return hashlib.sha256(raw).hexdigest()


def write_output(path: Path | str, data: bytes | str, *, option: str | None = None,
                 location: SourceLocation | None = None, replace_if_sha256: str | None = None) -> None:
    """Write ``data`` (str as UTF-8) to the output file ``path`` atomically, and record it in the
    folder's ledger.

    The temporary is created exclusively beside ``path`` and written through its descriptor;
    it is moved into place by :func:`commit_file`, which replaces an existing file only if the
    ledger vouches for it at that moment (or, with ``replace_if_sha256``, if it still has that
    sha256: a file the command read and rewrites, such as a history).

    Raises
    ------
    LbsceneUserError
        ``LB611`` if a file appeared or changed meanwhile, ``LB610`` where nothing can be written
        (a full disk: nothing is changed), ``LB612`` for one of the run's inputs.
    """
    path = Path(path)
    raw = data.encode("utf-8") if isinstance(data, str) else bytes(data)
    _check_not_input(path, option, location)
    _mkdirs(path.parent, option)
    clean_leftovers(path.parent, path.name)
    try:
        with _dir_fd(path.parent) as dfd:
            if replace_if_sha256 is not None:
                def may_replace(dir_fd: int, name: str) -> bool:
                    return _mismatch(name, dir_fd, replace_if_sha256) is None
            else:
                may_replace = _ledger_may_replace(path.name, dfd)
            write_via_temporary(dfd, path, raw, may_replace=may_replace, option=option, location=location)
    except OSError as exc:
        err = _write_error(exc, path, option, location)
        if err is None:
            raise
        raise err from None
    _record(path, hashlib.sha256(raw).hexdigest(), len(raw))


@contextmanager
def output_path(path: Path | str, suffix: str = ".tmp", *, option: str | None = None,
                record: bool = True, location: SourceLocation | None = None) -> Iterator[Path]:
    """Yield a path for a writer that needs one (matplotlib, OpenEXR, ``np.save``); on success the
    file written there replaces ``path`` and is recorded in the folder's ledger.  On any exception
    nothing is left behind.

    The path lies in a private folder (mode ``0700``, lbscene's temporary pattern) made inside
    ``path``'s folder, so nobody else can swap it for a link while the writer opens it by name.
    What the writer leaves must be a regular file; it is moved into place by
    :func:`commit_file` (ownership checked at that moment).  ``suffix`` is the temporary's
    extension, for writers that infer the format from the name.

    Raises
    ------
    LbsceneUserError
        As :func:`write_output`; ``LB610`` also when the writer left something other than a
        regular file.
    """
    path = Path(path)
    _check_not_input(path, option, location)
    _mkdirs(path.parent, option)
    clean_leftovers(path.parent, path.name)
    try:
        private = Path(tempfile.mkdtemp(prefix=_tmp_prefix(path), dir=path.parent))
    except OSError as exc:
        raise _err("LB610", f"cannot write: {exc.strerror}", path, option, location) from None
    inner = private / f"output{suffix}"
    try:
        try:
            yield inner
            with _dir_fd(private) as pfd, _dir_fd(path.parent) as dfd:
                try:
                    fd = os.open(inner.name, _O_NOFOLLOW_READ, dir_fd=pfd)
                except OSError as exc:
                    kind = "a symbolic link" if exc.errno == errno.ELOOP else "nothing"
                    raise _err("LB610", "the writer did not leave a regular file", path, option, location,
                               value=kind) from None
                try:
                    st = os.fstat(fd)
                    if not stat.S_ISREG(st.st_mode):
                        raise _err("LB610", "the writer did not leave a regular file", path, option,
                                   location, value="not a regular file")
                    sha = _sha_fd(fd, st)
                    os.fchmod(fd, 0o666 & ~_umask())
                    size = st.st_size
                finally:
                    os.close(fd)
                commit_file(pfd, inner.name, dfd, path.name, shown=path,
                            may_replace=_ledger_may_replace(path.name, dfd), option=option, location=location)
        except OSError as exc:
            err = _write_error(exc, path, option, location)
            if err is None:
                raise
            raise err from None
    finally:
        shutil.rmtree(private, ignore_errors=True)
    if record:
        _record(path, sha, size)


# --------------------------------------------------------------------------- folders


def temporary_dir_for(out_dir: Path | str, *, option: str | None = None) -> Path:
    """A fresh, empty, private (``0700``) sibling folder of ``out_dir`` to assemble it in (see
    :func:`replace_dir`, which gives it the usual permissions when it is moved into place);
    leftovers of interrupted runs beside it are removed first."""
    out_dir = Path(out_dir)
    _mkdirs(out_dir.parent, option)
    clean_leftovers(out_dir.parent, out_dir.name)
    tmp = _tmp_name(out_dir)
    try:
        tmp.mkdir(mode=0o700)
    except OSError as exc:
        raise _err("LB610", f"cannot write: {exc.strerror}", out_dir, option) from None
    return tmp


def carry_over(out_dir: Path | str, new_dir: Path | str, *, option: str | None = None) -> list[str]:
    """Take into ``new_dir`` (a folder being assembled to replace ``out_dir``) what ``out_dir``
    holds besides its own product: other lbscene products kept in it (a bake's sub-folder with its
    manifest, outputs recorded in a ledger), as hard links (copies where links are not possible)
    keeping their times, so that replacing ``out_dir`` loses nothing.  A path ``new_dir``
    already has is left to the new version.  Returns the relative paths taken.

    Raises
    ------
    LbsceneUserError
        ``LB611`` as :func:`verify_tree` for ``out_dir``.
    """
    out_dir, new_dir = Path(out_dir), Path(new_dir)
    if not out_dir.is_dir() or out_dir.is_symlink():
        return []
    scan = verify_tree(out_dir, option=option)
    taken = []
    for rel in scan.carried:
        src, dst = out_dir / rel, new_dir / rel
        if os.path.lexists(dst):
            continue
        dst.parent.mkdir(parents=True, exist_ok=True)
        try:
            os.link(src, dst, follow_symlinks=False)
        except OSError:
            shutil.copy2(src, dst, follow_symlinks=False)
        taken.append(rel)
    return taken


def fault_point(name: str) -> None:
    """Fault injection for the tests: when the environment variable ``LBSCENE_FAULT`` names this
    point, the process dies here, as under ``kill -9`` (``LBSCENE_FAULT=<point>``), or prints
    ``@@lbscene-fault <point>`` to stderr and waits to be signalled (``LBSCENE_FAULT=<point>:wait``)."""
    want = os.environ.get("LBSCENE_FAULT")
    if want == name:
        os._exit(70)
    if want == f"{name}:wait":
        import sys
        import time

        print(f"@@lbscene-fault {name}", file=sys.stderr, flush=True)
        time.sleep(600)


def replace_dir(tmp_dir: Path | str, out_dir: Path | str, *, option: str | None = None,
                location: SourceLocation | None = None) -> None:
    """Move a finished folder into place, replacing ``out_dir`` only if lbscene may.

    A new ``out_dir`` is taken with ``RENAME_NOREPLACE``.  An existing one is checked
    (:func:`verify_tree`: every file lbscene's and unchanged), then exchanged with the new
    folder in one atomic step (``RENAME_EXCHANGE``) and its old contents checked again where
    they now lie; if anything appeared meanwhile the exchange is undone and ``LB611`` raised.
    Where folders cannot be exchanged, the old folder is renamed to a sibling
    ``.<name>.lbold-<pid>-…`` right after the check; if the process dies between the two
    renames, the next run of the same output puts it back (:func:`restore_interrupted`).

    Raises
    ------
    LbsceneUserError
        ``LB611`` when ``out_dir`` holds, or came to hold, something lbscene may not replace.
    """
    out_dir, tmp_dir = Path(out_dir), Path(tmp_dir)
    os.chmod(tmp_dir, 0o777 & ~_umask())
    with _dir_fd(out_dir.parent) as pfd:
        try:
            if _renameat2(pfd, tmp_dir.name, pfd, out_dir.name, _RENAME_NOREPLACE):
                return
            if not os.path.lexists(out_dir):
                os.rename(tmp_dir.name, out_dir.name, src_dir_fd=pfd, dst_dir_fd=pfd)
                return
        except OSError as exc:
            if exc.errno not in (errno.EEXIST, errno.ENOTEMPTY):
                raise
        verify_tree(out_dir, option=option, location=location)
        with deferred_signals():      # a signal must not leave the old folder at a temporary's name
            if _renameat2(pfd, tmp_dir.name, pfd, out_dir.name, _RENAME_EXCHANGE):
                fault_point("replace")
                try:
                    verify_tree(tmp_dir, option=option, location=location, shown=out_dir)   # holds the old now
                except LbsceneUserError:
                    _renameat2(pfd, tmp_dir.name, pfd, out_dir.name, _RENAME_EXCHANGE)
                    raise
                shutil.rmtree(tmp_dir.name, dir_fd=pfd, ignore_errors=True)
                return
            old = _tmp_name(out_dir, kind="lbold")
            os.replace(out_dir, old)
            fault_point("replace")
            os.replace(tmp_dir, out_dir)
            shutil.rmtree(old, ignore_errors=True)


def restore_interrupted(out_dir: Path) -> None:
    """If an interrupted :func:`replace_dir` left ``out_dir`` missing and its old copy aside, put
    the old copy back (called before a new run of the same output)."""
    out_dir = Path(out_dir)
    if os.path.lexists(out_dir):
        return
    try:
        entries = list(os.scandir(out_dir.parent))
    except OSError:
        return
    for e in entries:
        m = _TMP_RE.match(e.name)
        if not m or m["name"] != out_dir.name or m["kind"] != "lbold":
            continue
        try:
            st = e.stat(follow_symlinks=False)
        except OSError:
            continue
        if st.st_uid == os.geteuid() and stat.S_ISDIR(st.st_mode) and owner_gone(int(m["pid"]), m["tok"]):
            try:
                os.rename(e.path, out_dir)
            except OSError:
                pass
            return

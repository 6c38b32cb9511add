"""Atomic file writes and output-folder rules.

Every output goes to a temporary file in the same folder and is renamed into place, so an
interrupted run never leaves a half-written file. Nothing that exists is overwritten unless the
caller says so (``--overwrite``).
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import tempfile
import time
from pathlib import Path
from collections.abc import Iterator

import numpy as np

from .errors import InputError, OutputExistsError


# ---- Ctrl-C -----------------------------------------------------------------------------------------------
# Some libraries catch BaseException around their imports (trimesh does), so a Ctrl-C that lands there is
# swallowed and the run would go on to write its output. The CLI's SIGINT handler also sets this flag, and
# every write checks it before it makes anything visible.
_INTERRUPTED = False


def note_interrupt() -> None:
    """Record a Ctrl-C (called by the CLI's SIGINT handler)."""
    global _INTERRUPTED
    _INTERRUPTED = True


def clear_interrupt() -> None:
    global _INTERRUPTED
    _INTERRUPTED = False


def check_interrupted() -> None:
    """Raise KeyboardInterrupt if a Ctrl-C arrived, even one a library swallowed."""
    if _INTERRUPTED:
        raise KeyboardInterrupt


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike, suffix: str | None = None) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; on success it is renamed onto ``path``. An OS error on the
    temporary file names ``path`` (the user never chose the temporary name)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=suffix or path.suffix or ".tmp", dir=path.parent)
    except OSError as exc:
        raise OSError(exc.errno, exc.strerror, str(path)) from None
    os.close(fd)
    tmp_path = Path(tmp)
    try:
        yield tmp_path
        check_interrupted()
        # mkstemp creates 0600 files; outputs get the usual permissions (0666 less the umask)
        os.chmod(tmp_path, 0o666 & ~_umask())
        os.replace(tmp_path, path)
    except OSError as exc:
        if exc.filename is not None and os.fspath(exc.filename) == tmp:
            raise OSError(exc.errno, exc.strerror, str(path)) from exc
        raise
    finally:
        if tmp_path.exists():
            tmp_path.unlink()


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def atomic_write_bytes(path: str | os.PathLike, data: bytes) -> Path:
    path = Path(path)
    try:
        with atomic_path(path) as tmp, open(tmp, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
    except OSError as exc:
        if exc.filename is None:  # a failed write names no file: name the one being written
            raise OSError(exc.errno, exc.strerror, str(path)) from exc
        raise
    return path


def atomic_write_text(path: str | os.PathLike, text: str) -> Path:
    return atomic_write_bytes(path, text.encode("utf-8"))


def same_file(a: str | os.PathLike, b: str | os.PathLike) -> bool:
    """Whether two paths name one existing file (an output that would replace its own input)."""
    try:
        return os.path.samefile(a, b)
    except OSError:
        return False


def check_writable_file(path: str | os.PathLike, overwrite: bool) -> Path:
    """Refuse to replace an existing file unless ``overwrite``."""
    path = Path(path)
    if path.exists() and not overwrite:
        raise OutputExistsError(f"{path} exists; pass --overwrite to replace it, or choose another output")
    return path


def prepare_output_dir(path: str | os.PathLike, overwrite: bool) -> Path:
    """Create an output folder; refuse a non-empty existing one unless ``overwrite``.

    With ``overwrite`` the files coastforge writes are replaced; other files in the folder are kept.
    """
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise InputError(f"output {path} exists and is not a folder; choose a folder path with --out")
    if path.is_dir() and any(path.iterdir()) and not overwrite:
        raise OutputExistsError(
            f"output folder {path} exists and is not empty; pass --overwrite to replace coastforge's files in it, "
            "or choose another --out"
        )
    path.mkdir(parents=True, exist_ok=True)
    return path


def png_bytes(array: np.ndarray, compression: int = 1, fast_filter: bool = True) -> bytes:
    """A uint8/uint16 gray, RGB or RGBA array (RGB order) encoded as PNG.

    Compression level 1 (of 9): about 4x faster than OpenCV's default for ~15 % larger files; the
    pipeline writes a dozen full-size rasters per scene. ``fast_filter``: the "sub" row filter only
    instead of libpng's per-row choice of all five (half the CPU again, ~3 % larger files)."""
    import cv2

    a = np.asarray(array)
    if a.dtype not in (np.uint8, np.uint16):
        raise TypeError(f"PNG needs uint8 or uint16, got {a.dtype}")
    if a.ndim == 3 and a.shape[2] == 3:
        a = cv2.cvtColor(np.ascontiguousarray(a), cv2.COLOR_RGB2BGR)  # one pass, not a strided copy
    elif a.ndim == 3 and a.shape[2] == 4:
        a = cv2.cvtColor(np.ascontiguousarray(a), cv2.COLOR_RGBA2BGRA)
    params = [cv2.IMWRITE_PNG_COMPRESSION, int(compression)]
    if fast_filter and hasattr(cv2, "IMWRITE_PNG_FILTER"):  # OpenCV >= 4.10
        params += [cv2.IMWRITE_PNG_FILTER, cv2.IMWRITE_PNG_FILTER_SUB]
    ok, buf = cv2.imencode(".png", np.ascontiguousarray(a), params)
    if not ok:  # pragma: no cover - cv2 fails only on impossible shapes
        raise OSError("could not encode a PNG")
    return buf.tobytes()


def write_png(path: str | os.PathLike, array: np.ndarray, compression: int = 1, fast_filter: bool = True) -> Path:
    """Write a uint8/uint16 gray or RGB(A) array as PNG, atomically. RGB arrays are in RGB order."""
    return atomic_write_bytes(path, png_bytes(array, compression, fast_filter))


def write_jpeg(path: str | os.PathLike, rgb: np.ndarray, quality: int = 92) -> Path:
    import cv2

    ok, buf = cv2.imencode(".jpg", np.ascontiguousarray(rgb[:, :, ::-1]), [cv2.IMWRITE_JPEG_QUALITY, quality])
    if not ok:
        raise OSError(f"could not encode JPEG for {path}")
    return atomic_write_bytes(path, buf.tobytes())


def read_png(path: str | os.PathLike) -> np.ndarray:
    """Read a PNG as stored (uint8/uint16, gray or RGB in RGB order)."""
    import cv2

    a = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if a is None:
        raise InputError(f"cannot read image {path}: missing or not a PNG/JPEG")
    if a.ndim == 3 and a.shape[2] == 3:
        a = a[:, :, ::-1]
    elif a.ndim == 3 and a.shape[2] == 4:
        a = a[:, :, [2, 1, 0, 3]]
    return np.ascontiguousarray(a)


def write_geotiff(path: str | os.PathLike, array: np.ndarray, transform, crs=None, nodata=None,
                  zlevel: int = 1) -> Path:
    """Write a (H, W) or (B, H, W) array as a compressed GeoTIFF, atomically.

    Deflate (readable everywhere) at ``zlevel`` 1 of 9: half the CPU of GDAL's default level 6 for ~5 %
    larger files."""
    import rasterio
    from affine import Affine

    a = array if array.ndim == 3 else array[None]
    profile = dict(
        driver="GTiff", width=a.shape[2], height=a.shape[1], count=a.shape[0], dtype=str(a.dtype),
        transform=Affine(*transform), crs=crs, compress="deflate", zlevel=int(zlevel), nodata=nodata,
        # the floating-point predictor makes smooth height maps compress several times better
        predictor=3 if np.issubdtype(a.dtype, np.floating) else 2,
    )
    if a.shape[1] >= 256 and a.shape[2] >= 256:
        profile.update(tiled=True, blockxsize=256, blockysize=256)
    # encoded in memory, then written by atomic_write_bytes: a full disk or a read-only folder is then our
    # one clear error, not libtiff's own lines on stderr before it (the file is compressed: a scene grid's
    # height map is tens of MB at most)
    from rasterio.io import MemoryFile

    try:
        with MemoryFile() as mem:
            with mem.open(**profile) as dst:
                dst.write(a)
            data = mem.read()
    except rasterio.errors.RasterioError as exc:  # GDAL says "Write failed" and no errno: find out why
        raise _write_error(Path(path), exc) from None
    return atomic_write_bytes(path, data)


def _write_error(path: Path, exc: Exception) -> OSError:
    """An OSError naming ``path`` for a library's write failure that carries no errno (GDAL, libtiff)."""
    import errno

    try:
        st = os.statvfs(path.parent)
        if st.f_flag & os.ST_RDONLY:
            return OSError(errno.EROFS, os.strerror(errno.EROFS), str(path))
        if st.f_bavail * st.f_frsize < 1 << 20:
            return OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(path))
    except OSError:
        pass
    return OSError(errno.EIO, str(exc).replace(" See previous exception for details.", ""), str(path))


# ---- all-or-nothing output folders ---------------------------------------------------------------------
# A run writes a whole folder into a staging folder beside it and swaps it into place only when everything
# it was asked for is complete. One writer per folder: a lock file beside it (flock, released by the kernel
# when the process dies, so a killed run never leaves a stale lock).

MARKER = ".coastforge-output.json"  # written into every folder a run completes: "coastforge made this"
STAGING_SUFFIX = ".coastforge-staging"
_OLD_SUFFIX = ".coastforge-old"


def _siblings(out: Path) -> tuple[Path, Path, Path]:
    """(lock file, staging folder, old folder) of the output folder ``out``."""
    return (out.parent / f".{out.name}.coastforge-lock", out.parent / f"{out.name}{STAGING_SUFFIX}",
            out.parent / f".{out.name}{_OLD_SUFFIX}")


def os_error_message(exc: OSError, path: str | os.PathLike | None = None) -> str:
    """A one-line, user-facing description of an OS error on ``path`` (what, where, what to do)."""
    import errno

    where = str(path or exc.filename or "a file of the output")
    hints = {
        errno.ENOSPC: "the disk is full; free some space or write somewhere else",
        errno.EDQUOT: "the disk quota is exceeded; free some space or write somewhere else",
        errno.EROFS: "the file system is read-only; choose a writable --out",
        errno.EACCES: "permission denied; choose a folder you can write to",
        errno.EPERM: "operation not permitted; choose a folder you can write to",
        errno.ENOTDIR: "a part of this path is a file, not a folder; choose another path",
        errno.EISDIR: "this is a folder where a file was expected; choose another path",
        errno.ELOOP: "the path has a symbolic-link loop; choose another path",
        errno.ENAMETOOLONG: "the path is too long; choose a shorter one",
        errno.ENOENT: "it does not exist, or its folder does not accept new entries (a virtual file system?)",
        errno.EEXIST: "it already exists",
    }
    hint = hints.get(exc.errno or -1, exc.strerror or str(exc))
    return f"cannot write {where}: {hint}"


def check_output_parent(out: Path) -> None:
    """Refuse, before any work, an output path whose folder cannot be made or written."""
    try:
        if out.is_symlink() and not out.is_dir():
            raise InputError(f"output {out} is a symbolic link that leads nowhere (broken, or a loop); "
                             "choose another --out")
        if out.exists() and not out.is_dir():
            raise InputError(f"output {out} exists and is not a folder; choose a folder path with --out")
        anc = out.parent
        while not anc.exists():
            if anc.is_symlink():  # a dangling link: mkdir would fail later
                raise InputError(f"output {out}: {anc} is a broken symbolic link; choose another --out")
            anc = anc.parent
        if not anc.is_dir():
            raise InputError(f"output {out}: {anc} is a file, not a folder; choose another --out")
        if not os.access(anc, os.W_OK | os.X_OK):
            raise InputError(f"output {out}: cannot write in {anc} (permission denied or read-only); "
                             "choose a folder you can write to")
    except OSError as exc:  # loops, names too long, /proc oddities
        raise InputError(f"output {out}: {os_error_message(exc, out)}") from None


def is_coastforge_output(path: Path) -> bool:
    """A folder a coastforge run completed (its marker), or one in the older layouts (a scene or library)."""
    return any((path / n).is_file() for n in (MARKER, "scene.json", "library.json", "segmentation.json"))


# written into a completed folder later, outside a staged run: `coastforge report` (report.html beside
# scene.json), `coastforge batch` (an item's .done marker) and `make demo` (its .coastforge-demo mark)
_LATE_FILES = frozenset({"report.html", ".done", ".coastforge-demo"})


def _all_files(folder: Path) -> set[str]:
    out = set()
    for root, _dirs, files in os.walk(folder):
        for f in files:
            out.add(os.path.relpath(os.path.join(root, f), folder))
    return out


def _listed_files(folder: Path) -> set[str] | None:
    """The files the run that completed ``folder`` wrote (its marker's list); None when unknown (no marker,
    or one written before markers listed their files)."""
    try:
        files = json.loads((folder / MARKER).read_text(encoding="utf-8")).get("files")
    except (OSError, ValueError, AttributeError):
        return None
    return set(files) if isinstance(files, list) and all(isinstance(f, str) for f in files) else None


def foreign_files(folder: Path) -> list[str]:
    """Files in a folder coastforge completed that no coastforge run wrote there (a user's own files,
    e.g. the input image copied into the scene folder). Empty when the folder's marker lists no files."""
    listed = _listed_files(folder)
    if listed is None:
        return []
    return sorted(f for f in _all_files(folder) - listed
                  if f != MARKER and os.path.basename(f) not in _LATE_FILES and not f.startswith(".nfs"))


def _files_written(staging: Path, out: Path, update: bool) -> list[str]:
    """What the marker of a completed run lists: every file of ``staging`` - except, for an update, the files
    it only carried over from ``out`` that no run of ours wrote (they stay the user's)."""
    files = _all_files(staging) - {MARKER}
    old = None
    if update and out.is_dir():  # a folder no run of ours made (e.g. export --out into one) lists nothing of it
        old = _listed_files(out) if is_coastforge_output(out) else set()
    if old is not None:
        def carried(f):
            try:
                return os.path.samefile(staging / f, out / f)
            except OSError:
                return False

        files = {f for f in files if f in old or not carried(f)}
    return sorted(files)


class FolderLock:
    """One writer per output folder: an exclusive, non-blocking flock on a file beside it."""

    def __init__(self, out: Path, command: str = ""):
        self.out, self.command = out, command
        self.path = _siblings(out)[0]
        self.fd: int | None = None

    def acquire(self) -> FolderLock:
        import fcntl

        while True:
            fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                other = b""
                try:
                    other = os.pread(fd, 4096, 0)
                finally:
                    os.close(fd)
                raise OutputBusyError(self.out, other) from None
            # the holder may have removed the file between our open and our lock: lock the file on disk
            try:
                same = os.fstat(fd).st_ino == os.stat(self.path).st_ino
            except FileNotFoundError:
                same = False
            if same:
                break
            os.close(fd)
        self.fd = fd
        info = {"pid": os.getpid(), "command": self.command or "coastforge", "started": time.strftime("%Y-%m-%d %H:%M:%S")}
        try:  # who holds it, for the message of a second run; best effort (a full disk takes no bytes)
            os.ftruncate(fd, 0)
            os.pwrite(fd, json.dumps(info).encode(), 0)
        except OSError:
            pass
        return self

    def release(self) -> None:
        if self.fd is None:
            return
        with contextlib.suppress(OSError):
            self.path.unlink(missing_ok=True)  # while still holding it: see acquire's inode check
        os.close(self.fd)
        self.fd = None

    def __enter__(self) -> FolderLock:
        return self.acquire()

    def __exit__(self, *exc) -> None:
        self.release()


class OutputBusyError(OutputExistsError):
    """Another coastforge run is writing to the same output."""

    def __init__(self, out: Path, holder: bytes = b""):
        who = "another coastforge run"
        try:
            info = json.loads(holder.decode() or "{}")
            who = f"another coastforge run (pid {info['pid']}, started {info['started']}: {info['command']})"
        except (ValueError, KeyError, UnicodeDecodeError):
            pass
        super().__init__(f"{who} is writing to {out}; wait for it to finish, or choose another --out")


def _recover(out: Path) -> list[str]:
    """Undo what a killed run left beside ``out`` (the lock is held): a swap cut half-way is rolled back,
    a staging folder is removed. Returns notes for the user."""
    _lock, staging, old = _siblings(out)
    notes = []
    if old.exists():
        if not out.exists():  # killed between the two renames of a swap: the previous folder comes back
            os.rename(old, out)
            notes.append(f"restored {out} from an interrupted run")
        else:
            shutil.rmtree(old, ignore_errors=True)
    if staging.exists():
        shutil.rmtree(staging)
        notes.append(f"removed {staging}, left by an earlier run that failed or was stopped")
    return notes


def _hardlink_copy(src: Path, dst: Path) -> None:
    """``dst`` as a copy of folder ``src`` whose files are hard links (instant, no extra space); atomic
    writes replace a linked file by a new one, so the original is never touched. Falls back to copies."""
    def link(s, d):
        try:
            os.link(s, d)
        except OSError:
            shutil.copy2(s, d)

    shutil.copytree(src, dst, copy_function=link, symlinks=True)


def _written_into(staging: Path, out: Path) -> bool:
    """Whether the run wrote any file into ``staging``: one that ``out`` lacks, or holds as another file
    (the staging copy of an update shares its unchanged files with ``out`` as hard links)."""
    for f in _all_files(staging):
        try:
            if not (out / f).exists() or not os.path.samefile(staging / f, out / f):
                return True
        except OSError:
            return True
    return False


def _swap_in(staging: Path, out: Path) -> None:
    old = _siblings(out)[2]
    if out.exists():
        os.rename(out, old)
        os.rename(staging, out)
        shutil.rmtree(old, ignore_errors=True)
    else:
        os.rename(staging, out)


def _add_note(exc: BaseException, note: str) -> None:
    """``exc.add_note(note)`` where Python has it (3.11+); on 3.10 the exception goes on without the note."""
    add = getattr(exc, "add_note", None)
    if add is not None:
        add(note)


@contextlib.contextmanager
def output_folder(out: str | os.PathLike, *, overwrite: bool = False, update: bool = False, command: str = "",
                  notes: list[str] | None = None, inputs=()) -> Iterator[Path]:
    """Write the folder ``out`` all-or-nothing; yields the staging folder to write into.

    ``update=False``: the run makes the whole folder. An existing non-empty ``out`` is refused unless
    ``overwrite``, and then replaced whole (no stale file survives) - but only if coastforge made it.
    ``update=True``: the run changes an existing folder (a scene's exports, its terrain): staging starts
    as a hard-linked copy of it. Either way ``out`` changes only when the block completes; a failure or a
    kill leaves it as it was, plus the staging folder, which the next run removes. ``notes`` receives what
    recovery did. ``inputs``: the run's input files; --overwrite refuses to replace a folder holding one
    (even one whose marker predates the list of written files)."""
    out = Path(out)
    check_output_parent(out)
    if out.is_symlink():  # a link to a folder: write the folder it names (swapping would replace the link)
        out = out.resolve()
    if not update and out.is_dir() and any(out.iterdir()):
        if not overwrite:
            raise OutputExistsError(f"output folder {out} exists and is not empty; pass --overwrite to replace "
                                    "it, or choose another --out")
        if not is_coastforge_output(out):
            raise OutputExistsError(f"output folder {out} holds files coastforge did not write; --overwrite "
                                    "replaces only a folder an earlier run made: choose another --out")
        for p in inputs:
            if p is None or not Path(p).exists():
                continue
            where = ("is the output folder" if Path(p).resolve() == out.resolve() else
                     "is inside the output folder" if out.resolve() in Path(p).resolve().parents else None)
            if where:
                raise OutputExistsError(f"{p} {where} {out}, which --overwrite replaces whole; it is an input of "
                                        "this run: move it out of it first, or choose another --out")
        foreign = foreign_files(out)
        if foreign:
            shown = ", ".join(foreign[:5]) + (f" and {len(foreign) - 5} more" if len(foreign) > 5 else "")
            raise OutputExistsError(f"output folder {out} holds {len(foreign)} file(s) coastforge did not write "
                                    f"({shown}); --overwrite replaces the whole folder and would delete them: move "
                                    "them out of it, or choose another --out")
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(os_error_message(exc, out.parent)) from None
    staging = _siblings(out)[1]
    try:
        lock = FolderLock(out, command).acquire()
    except OSError as exc:
        if isinstance(exc, OutputExistsError):
            raise
        raise InputError(os_error_message(exc, out)) from None
    try:
        (notes if notes is not None else []).extend(_recover(out))
        if update and out.is_dir():
            _hardlink_copy(out, staging)
        else:
            staging.mkdir()
        try:
            yield staging
        except BaseException as exc:
            if staging.exists() and not _written_into(staging, out):  # failed before writing: nothing to keep
                shutil.rmtree(staging, ignore_errors=True)
                if isinstance(exc, KeyboardInterrupt):  # (an error's own message says enough)
                    _add_note(exc, f"{out} is unchanged")
            elif staging.exists():
                _add_note(exc, f"{out} is unchanged; the partial output is in {staging} (the next run into {out} "
                          "removes it)")
            raise
        atomic_write_text(staging / MARKER, json.dumps({"tool": "coastforge", "command": command,
                                                        "completed": time.strftime("%Y-%m-%d %H:%M:%S"),
                                                        "files": _files_written(staging, out, update)}) + "\n")
        check_interrupted()
        _swap_in(staging, out)
    finally:
        lock.release()

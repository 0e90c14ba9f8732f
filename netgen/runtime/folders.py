"""Output folders as transactions: a run writes into a staging folder inside its output folder
and commits the set under a lock, with a manifest naming every file and its SHA-256
(OutputFolder); check_manifest tells whether a folder still holds the set its manifest names."""

from __future__ import annotations

import errno
import fcntl
import hashlib
import json
import os
import shutil
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from ..core.errors import DiskFullError, InputError
from ..core.files import umask, write_atomic
from .interrupts import check, held

STAGING = ".netgen-staging-"
MANIFEST = ".manifest.json"  # <set name>.manifest.json: the complete set a run committed
FAILED = ".failed"  # <set name>.failed/: the files of the last run that failed
FAILED_NOTE = "FAILED.txt"


class OutputFolder:
    """One run's outputs in `folder` as a transaction. The run writes into `stage` (a hidden
    staging folder inside `folder`, so the renames stay on one file system); `commit` moves the
    staged files into place under an exclusive lock on the folder (two runs into one folder
    commit one after the other: the folder holds the last one's complete set), removes the files
    the previous run of the same set wrote that this one did not (named by its manifest; files
    netgen did not write are never touched) and writes `<name>.manifest.json` naming the new set
    with the SHA-256 of each file. A run that ends without committing leaves the folder as it
    was; a failed one (not an interrupt) with `keep_failed` moves its files to `<name>.failed/`.
    SIGINT/SIGTERM are held over the commit and the clean-up (netgen.runtime.interrupts.held), so an
    interrupt never leaves a half-moved set or a staging folder. `shared`: sub-folders of
    `folder` the run reaches through `stage` (caches such as osdi/), linked, not staged.
    `legacy`: the names this set's files have, replaced or removed as its own when the folder
    has no manifest yet (written by a netgen before manifests)."""

    def __init__(
        self,
        folder: str | Path,
        name: str,
        info: dict | None = None,
        keep_failed: bool = False,
        shared: tuple[str, ...] = (),
        legacy: tuple[str, ...] = (),
    ):
        self.folder, self.name, self.info = Path(folder), name, dict(info or {})
        self.keep_failed, self.shared, self.legacy = keep_failed, shared, legacy
        self.manifest = self.folder / f"{name}{MANIFEST}"
        self.stage: Path = self.folder
        self.committed = False
        self._created = False
        self._made: list[Path] = []  # shared sub-folders this run created
        self._lock: int | None = None

    def __enter__(self) -> OutputFolder:
        with held():
            self._created = not self.folder.exists()
            with folder_lock(self.folder, create=True):  # against a run's clean-up of the same folder
                remove_stale_stages(self.folder)
                self.stage = Path(tempfile.mkdtemp(prefix=f"{STAGING}{self.name}-", dir=self.folder))
                try:
                    os.chmod(self.stage, 0o777 & ~umask())
                    self._lock = os.open(self.stage, os.O_RDONLY)
                    fcntl.flock(self._lock, fcntl.LOCK_EX)  # alive: remove_stale_stages leaves it
                    for sub in self.shared:
                        if not (self.folder / sub).exists():
                            (self.folder / sub).mkdir()
                            self._made.append(self.folder / sub)
                        os.symlink(Path("..") / sub, self.stage / sub)
                except BaseException:
                    self._drop_stage()
                    raise
        return self

    def commit(self, written: list[Path] | None = None) -> list[Path]:
        """Move the staged files into the folder as one set (see the class); the final paths of
        `written` (staged paths), in their order."""
        check()  # an interrupt a library swallowed: no commit
        with held(), folder_lock(self.folder):
            new = staged_files(self.stage)
            check_owners(self.folder, self.name, new)
            before = manifest_files(self.manifest) if self.manifest.exists() else list(self.legacy)
            old = set(before) - set(new) - owned_by_others(self.folder, self.name)
            self.manifest.unlink(missing_ok=True)  # no manifest names a set while it moves
            for rel in new:
                os.replace(self.stage / rel, self.folder / rel)
            for rel in sorted(old):
                (self.folder / rel).unlink(missing_ok=True)
            write_atomic(self.manifest, manifest_text(self.folder, self.name, new, self.info))
            failed = self.folder / f"{self.name}{FAILED}"
            if (failed / FAILED_NOTE).exists():  # an earlier failure, superseded
                shutil.rmtree(failed, ignore_errors=True)
            self._drop_stage()
            self.committed = True
        return [self.folder / Path(p).relative_to(self.stage) for p in (written or [])]

    def __exit__(self, kind, exc, tb) -> None:
        if self.committed:
            return
        full = disk_problem(exc, self.stage)
        with held(), folder_lock(self.folder):
            keep = self.keep_failed and exc is not None and not isinstance(exc, KeyboardInterrupt) and not full
            if keep and staged_files(self.stage):
                self._keep_failed(exc)
            else:
                self._drop_stage()
            if self._created and not any(self.folder.iterdir()):
                self.folder.rmdir()  # a folder this run made and left empty
        if full:
            raise DiskFullError(
                f"{self.folder}: {full} while writing the run's files (the partial set was removed, the folder "
                "holds what it held before); fix: free space on that file system (or raise the quota, or make it "
                "writable), or give another output folder with -o, then run again"
            ) from exc

    def failed_path(self, text: str) -> str:
        """`text` (an error message) with the staging folder's paths replaced by the folder its
        files are kept in after a failure."""
        return text.replace(str(self.stage), str(self.folder / f"{self.name}{FAILED}"))

    def _keep_failed(self, exc: BaseException) -> None:
        """The failed run's files, for diagnosis, in <name>.failed/ (an earlier one replaced), with
        the links to the shared folders, so its netlist reruns there as netgen's message says."""
        failed = self.folder / f"{self.name}{FAILED}"
        if failed.exists() and (failed / FAILED_NOTE).exists():
            shutil.rmtree(failed, ignore_errors=True)
        if failed.exists():  # not ours: leave it, drop the run's files
            self._drop_stage()
            return
        (self.stage / FAILED_NOTE).write_text(
            f"this run failed; the folder above holds the last complete set ({self.manifest.name})\n\n{exc}\n",
            encoding="utf-8",
        )
        self._unlock()
        os.replace(self.stage, failed)  # its links ../<shared> resolve from there as from the stage
        self._clean_made()
        for sub in self.shared:  # a link to a shared folder _clean_made removed
            if not (failed / sub).exists():
                (failed / sub).unlink(missing_ok=True)

    def _drop_stage(self) -> None:
        """Remove the staging folder (and the shared folders this run made and left empty)."""
        self._unlock()
        shutil.rmtree(self.stage, ignore_errors=True)
        self._clean_made()

    def _clean_made(self) -> None:
        """Remove the shared folders this run made if they stayed empty and no other run is
        staging here (the caller holds the folder lock)."""
        if any(self.folder.glob(f"{STAGING}*")):
            return
        for made in self._made:
            if made.is_dir() and not any(made.iterdir()):
                made.rmdir()

    def _unlock(self) -> None:
        if self._lock is not None:
            os.close(self._lock)
            self._lock = None


FULL = {errno.ENOSPC: "the disk is full", errno.EDQUOT: "the disk quota is exceeded", errno.EROFS: "read-only"}


def disk_problem(exc: BaseException | None, stage: Path) -> str:
    """Why a failed run could not write its files: an OSError of a full disk, an exceeded quota or a
    read-only file system, or any failure (a simulator's, whose writes failed in another process)
    while the staging folder's file system has no free blocks; '' otherwise."""
    if exc is None or isinstance(exc, KeyboardInterrupt):
        return ""
    if isinstance(exc, OSError) and exc.errno in FULL:
        return FULL[exc.errno]
    try:
        return FULL[errno.ENOSPC] if os.statvfs(stage).f_bavail == 0 else ""
    except OSError:
        return ""


@contextmanager
def folder_lock(folder: Path, create: bool = False) -> Iterator[None]:
    """An exclusive flock on the folder itself (no lock file left in it); waits for another
    run's commit or clean-up to finish. create: make the folder first, and again if another
    run's clean-up removed it (empty, made by that run) while this one waited."""
    while True:
        if create:
            folder.mkdir(parents=True, exist_ok=True)
        fd = os.open(folder, os.O_RDONLY)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX)
            try:
                same = os.path.samestat(os.fstat(fd), os.stat(folder))
            except FileNotFoundError:
                same = False
            if same or not create:
                yield
                return
        finally:
            os.close(fd)


def remove_stale_stages(folder: Path) -> None:
    """Remove the staging folders of runs that died without cleaning up (SIGKILL, a crash):
    a live run holds a lock on its own staging folder."""
    for stage in folder.glob(f"{STAGING}*"):
        try:
            fd = os.open(stage, os.O_RDONLY)
        except OSError:
            continue
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            continue  # its run is alive
        finally:
            os.close(fd)
        shutil.rmtree(stage, ignore_errors=True)


def staged_files(stage: Path) -> list[str]:
    """The regular files a run wrote into its staging folder (links to shared folders excluded)."""
    return sorted(p.name for p in stage.iterdir() if p.is_file() and not p.is_symlink())


def manifest_files(manifest: Path) -> list[str]:
    """The file names an earlier run's manifest lists ([] when there is none or it is unreadable)."""
    try:
        files = json.loads(manifest.read_text(encoding="utf-8")).get("files", {})
    except (OSError, ValueError, AttributeError):
        return []
    return [f for f in files if isinstance(f, str) and "/" not in f and not f.startswith(".")]


def manifest_text(folder: Path, name: str, files: list[str], info: dict) -> str:
    """The manifest of a committed set: what wrote it, and each file with its SHA-256."""
    from .. import __version__

    doc = {
        "generator": f"netgen {__version__}",
        "set": name,
        **info,
        "files": {f: hashlib.sha256((folder / f).read_bytes()).hexdigest() for f in files},
    }
    return json.dumps(doc, indent=1) + "\n"


def check_owners(folder: Path, name: str, files: list[str] | tuple[str, ...]) -> None:
    """Refuse (InputError, exit 2) a set `name` that would write a file another set's manifest
    in `folder` names, or a manifest file itself: each set owns its files, so one run never
    replaces or removes another's (a model `summary` and a sigma-delta run's summary.json, models
    `a` with --format all and `a_xspice` both writing a_xspice.lib)."""
    own = folder / f"{name}{MANIFEST}"
    for manifest in sorted(folder.glob(f"*{MANIFEST}")):
        other = manifest.name[: -len(MANIFEST)]
        taken = sorted(set(files) & ({manifest.name} | set(manifest_files(manifest)))) if manifest != own else []
        if taken:
            raise InputError(
                str(folder),
                "output folder",
                f"the set {name!r} would write {', '.join(taken)}, which the set {other!r} there owns "
                f"(its {manifest.name})",
                f"write {name!r} into another -o folder, or rename the model so its files do not "
                f"collide with {other!r}'s",
            )


def owned_by_others(folder: Path, name: str) -> set[str]:
    """The files the manifests of sets other than `name` in `folder` name (never removed as this set's)."""
    own = folder / f"{name}{MANIFEST}"
    return {f for m in folder.glob(f"*{MANIFEST}") if m != own for f in [m.name, *manifest_files(m)]}


def check_manifest(folder: str | Path, name: str) -> list[str]:
    """What is wrong with the set `name` in `folder` against its manifest ([]: complete)."""
    folder = Path(folder)
    try:
        files = json.loads((folder / f"{name}{MANIFEST}").read_text(encoding="utf-8"))["files"]
    except (OSError, ValueError, KeyError) as exc:
        return [f"no readable manifest: {exc}"]
    problems = []
    for f, digest in files.items():
        path = folder / f
        if not path.is_file():
            problems.append(f"{f}: missing")
        elif hashlib.sha256(path.read_bytes()).hexdigest() != digest:
            problems.append(f"{f}: not the file the manifest names")
    return problems

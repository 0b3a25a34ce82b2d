"""The MicroPython stm32 port's internal-flash filesystem, laid into the emulated flash and
read back: ``hexhil run --firmware micropython.elf --main main.py [--fs DIR] [--fs-out DIR]``.

The stm32 port on an F411 keeps its ``/flash`` as a FAT volume of 128 blocks of 512 bytes
in the 64 KB from 0x0800_4000 (sectors 1-3 and the first 16 KB of sector 4); the block
device puts a partition table of its own in front in RAM, so the volume's boot sector is
the first block in flash. The image is made by ChaN's FatFs (the ``fatfs-ng`` package, the
library MicroPython's own oofatfs comes from), with every timestamp and the volume serial
fixed, so the same files give the same bytes. The firmware mounts it as it finds it and
runs ``main.py`` from it, as on the board.
"""
from __future__ import annotations

import datetime as dt
import types
from dataclasses import dataclass
from pathlib import Path

from hexhil.hil.mcu.elf_image import ElfImage
from hexhil.hil.mcu.flash_modules import module_files
from hexhil.protocol.errors import BadFile, UserError

FS_BASE, FS_SIZE = 0x08004000, 64 * 1024
BLOCK_BYTES = 512
STAMP = dt.datetime(2026, 1, 1)      # every file's time and the volume serial's source


@dataclass(frozen=True)
class FlashFiles:
    """What goes into ``/flash`` before the boot (``main`` as ``main.py``, ``folder``'s
    files as they are) and where its files go after the run (``out``)."""

    main: Path | None = None
    folder: Path | None = None
    out: Path | None = None

    @property
    def lays(self) -> bool:
        return self.main is not None or self.folder is not None

    def over(self, other: "FlashFiles | None") -> "FlashFiles":
        """These, with ``other``'s where these have none (a command's options over a
        case file's: ``--fs-out`` alone keeps the case's ``main``)."""
        if other is None:
            return self
        return FlashFiles(*(mine if mine is not None else theirs for mine, theirs in
                            ((self.main, other.main), (self.folder, other.folder),
                             (self.out, other.out))))


def _fatfs() -> types.ModuleType:
    """fatfs-ng with its clock fixed (its FatFs asks ``datetime.datetime.now()``)."""
    import fatfs
    import fatfs.wrapper as wrapper

    class Fixed(dt.datetime):
        @classmethod
        def now(cls, tz: dt.tzinfo | None = None) -> "Fixed":
            return cls.combine(STAMP.date(), STAMP.time())
    wrapper.datetime = types.SimpleNamespace(datetime=Fixed)
    return fatfs


def files_of(spec: FlashFiles) -> dict[str, bytes]:
    """The files to lay, path in the volume -> bytes (``UserError`` for a missing one): the
    modules main imports (hil/mcu/flash_modules.py) but those the folder holds as source,
    the folder's files, then main as ``/main.py``."""
    out: dict[str, bytes] = {}
    if spec.main is not None and spec.main.is_file():
        given = spec.folder
        out.update((rel, mpy) for rel, mpy in module_files(spec.main).items()
                   if given is None or not (given / (rel[1:-4] + ".py")).is_file())
    if spec.folder is not None:
        if not spec.folder.is_dir():
            raise BadFile(f"fs {spec.folder}: not a folder", params=("fs",))
        for p in sorted(spec.folder.rglob("*")):
            if p.is_file():
                out["/" + p.relative_to(spec.folder).as_posix()] = p.read_bytes()
    if spec.main is not None:
        if not spec.main.is_file():
            raise BadFile(f"main {spec.main}: not a file", params=("main",))
        out["/main.py"] = spec.main.read_bytes()
    return out


def image(files: dict[str, bytes]) -> bytes:
    """A FAT volume of FS_SIZE bytes holding ``files`` (``UserError`` if they do not fit)."""
    fatfs = _fatfs()
    store = bytearray(b"\xff" * FS_SIZE)
    part = fatfs.create_extended_partition(fatfs.RamDisk(store, sector_size=BLOCK_BYTES))
    part.mkfs()
    part.mount()
    try:
        for path, data in files.items():
            parent = path.rsplit("/", 1)[0]
            if parent:
                part.makedirs(parent, exist_ok=True)
            try:
                part.write_file(path, data)
            except Exception as exc:         # FatFs says FR_DENIED when the volume is full
                raise UserError(f"fs: {path} ({len(data)} bytes) does not fit in the "
                                f"{FS_SIZE // 1024} KB flash filesystem ({exc})",
                                params=("fs", "main")) from None
            if part.read_file(path) != data:
                raise UserError(f"fs: {path} did not fit whole in the flash filesystem",
                                params=("fs", "main"))
    finally:
        part.unmount()
    return bytes(store)


def laid(elf: ElfImage, spec: FlashFiles | None) -> bytes | None:
    """The volume to lay for ``spec`` (None when it lays nothing), checked against the
    ELF: a firmware with code or data in those sectors has no filesystem there."""
    if spec is None or not spec.lays:
        return None
    for seg in elf.segments:
        if seg.addr < FS_BASE + FS_SIZE and FS_BASE < seg.addr + len(seg.data):
            raise UserError(f"{elf.path.name} has data at 0x{seg.addr:08x}, inside the flash "
                            f"filesystem (0x{FS_BASE:08x}-0x{FS_BASE + FS_SIZE - 1:08x}): "
                            "main and fs need MicroPython's stm32 port for the F411",
                            params=("main", "fs"))
    return image(files_of(spec))


def read_back(volume: bytes, out: Path) -> list[str]:
    """The files of ``volume`` written under ``out``; their paths (``UserError`` where the
    firmware left no FAT volume there)."""
    fatfs = _fatfs()
    part = fatfs.create_extended_partition(fatfs.RamDisk(bytearray(volume),
                                                         sector_size=BLOCK_BYTES))
    try:
        part.mount()
    except Exception:
        raise UserError(f"fs_out {out}: the flash at 0x{FS_BASE:08x} holds no FAT filesystem "
                        "(the firmware made none, or erased it)", params=("fs_out",)) from None
    try:
        names: list[str] = []
        out.mkdir(parents=True, exist_ok=True)
        for root, _dirs, files in part.walk("/"):
            for name in files:
                src = f"{root.rstrip('/')}/{name}"
                dst = out / src.lstrip("/")
                dst.parent.mkdir(parents=True, exist_ok=True)
                dst.write_bytes(part.read_file(src))
                names.append(src)
        return names
    finally:
        part.unmount()

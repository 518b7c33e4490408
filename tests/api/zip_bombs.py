"""Deflate bombs for the upload tests: zips that declare a gigabyte of zeros in a megabyte,
made in a fraction of a second (tests/api/test_upload_fuzz.py, tests/api/test_hardening.py)."""

from __future__ import annotations

import io
import struct
import zipfile
import zlib

import numpy as np


def zeros_member(nbytes: int, *, npy: bool = False) -> bytes:
    """A zip with one member of ``nbytes`` zeros (``payload``, after an .npy header when
    ``npy``), ~1000:1.

    Deflated once per MiB, not streamed through ``zipfile`` (6 s for two bombs): after a full
    flush the compressor starts afresh, so every further MiB of zeros compresses to the same
    bytes, which are repeated.
    """
    prefix = b""
    if npy:
        header = io.BytesIO()
        np.lib.format.write_array_header_1_0(
            header, {"descr": "<f8", "fortran_order": False, "shape": (nbytes // 8,)}
        )
        prefix = header.getvalue()
    block, blocks = bytes(1 << 20), nbytes >> 20
    deflate = zlib.compressobj(6, zlib.DEFLATED, -15)
    head = deflate.compress(prefix) + deflate.flush(zlib.Z_FULL_FLUSH)
    one = deflate.compress(block) + deflate.flush(zlib.Z_FULL_FLUSH)
    assert deflate.compress(block) + deflate.flush(zlib.Z_FULL_FLUSH) == one
    compressed = head + one * blocks + deflate.flush()
    crc = zlib.crc32(prefix)
    for _ in range(blocks):
        crc = zlib.crc32(block, crc)
    info = zipfile.ZipInfo("payload", date_time=(2026, 1, 1, 0, 0, 0))
    info.compress_type, info.CRC = zipfile.ZIP_DEFLATED, crc
    info.compress_size, info.file_size = len(compressed), len(prefix) + (blocks << 20)
    return zip_with({}, {"payload": (info, compressed)})


def renamed(bomb: bytes, name: str) -> tuple[zipfile.ZipInfo, bytes]:
    """The bomb's member header and compressed bytes, to copy into another zip as ``name``."""
    with zipfile.ZipFile(io.BytesIO(bomb)) as z:
        info = z.getinfo("payload")
    name_len, extra_len = struct.unpack(
        "<HH", bomb[info.header_offset + 26 : info.header_offset + 30]
    )
    start = info.header_offset + 30 + name_len + extra_len  # the local header's own lengths
    raw = bomb[start : start + info.compress_size]
    copy = zipfile.ZipInfo(name, date_time=info.date_time)
    copy.compress_type, copy.CRC = info.compress_type, info.CRC
    copy.compress_size, copy.file_size = info.compress_size, info.file_size
    return copy, raw


def zip_with(members: dict[str, bytes], raw: dict[str, tuple[zipfile.ZipInfo, bytes]]) -> bytes:
    """A zip of ``members`` plus already-compressed members (bombs) written as they are."""
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as z:
        for name, content in members.items():
            z.writestr(name, content)
        for info, compressed in raw.values():
            info.header_offset = buf.tell()
            z.fp.write(info.FileHeader(zip64=True))
            z.fp.write(compressed)
            z.filelist.append(info)
            z.NameToInfo[info.filename] = info
            z.start_dir = buf.tell()
    return buf.getvalue()

"""Give an MP4 file's video frames chosen, uneven presentation times (a variable-frame-rate video).

Pure Python on the ISO base-media box tree (ISO/IEC 14496-12): a box is a 32-bit big-endian size
(1: a 64-bit size follows the type; 0: to the end of the file) and a four-character type; the
boxes below are containers whose payload is more boxes. :func:`set_frame_times` replaces the
video track's time-to-sample table ``stts`` (one delta per sample, run-length coded) and its
media timescale (``mdhd``), sets the durations that depend on them (``mdhd``, ``tkhd``, ``mvhd``,
the edit list ``elst``) and rewrites the sizes of the parent boxes; where ``moov`` lies before
``mdat``, the chunk offsets (``stco``/``co64``) are shifted by how far ``mdat`` moved. A track
with composition offsets (``ctts``, B-frames) is refused: its presentation times would not be the
ones asked for.

A phone records this way: frames stamped when the sensor delivered them, their spacing changing
with the exposure time, in a container whose ``stts`` holds the uneven deltas.
"""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np

__all__ = ["read_boxes", "set_frame_times"]

_CONTAINERS = {b"moov", b"trak", b"mdia", b"minf", b"stbl", b"edts", b"dinf"}


class _Box:
    """One box: its type, its payload (bytes) or its children, and where it was in the file."""

    def __init__(self, kind: bytes, payload: bytes | None, children: list | None, start: int,
                 end: int):
        self.kind, self.payload, self.children, self.start, self.end = kind, payload, children, start, end

    def find(self, *path: bytes) -> list:
        """The boxes at ``path`` below this one (all matches at each level)."""
        found = [self]
        for kind in path:
            found = [c for b in found for c in (b.children or []) if c.kind == kind]
        return found

    def encode(self) -> bytes:
        body = self.payload if self.children is None else b"".join(c.encode() for c in self.children)
        size = 8 + len(body)
        if size < 2**32:
            return struct.pack(">I4s", size, self.kind) + body
        return struct.pack(">I4sQ", 1, self.kind, size + 8) + body


def _parse(data: bytes, start: int, end: int) -> list:
    boxes = []
    pos = start
    while pos + 8 <= end:
        size, kind = struct.unpack_from(">I4s", data, pos)
        header = 8
        if size == 1:
            size = struct.unpack_from(">Q", data, pos + 8)[0]
            header = 16
        elif size == 0:
            size = end - pos
        if size < header or pos + size > end:
            raise ValueError(f"corrupt MP4 box {kind!r} at byte {pos} (size {size})")
        body_start, box_end = pos + header, pos + size
        if kind in _CONTAINERS:
            boxes.append(_Box(kind, None, _parse(data, body_start, box_end), pos, box_end))
        else:
            boxes.append(_Box(kind, data[body_start:box_end], None, pos, box_end))
        pos = box_end
    return boxes


def read_boxes(path: str | Path) -> list:
    """The top-level boxes of an MP4 file (a tree of ``_Box``)."""
    data = Path(path).read_bytes()
    return _parse(data, 0, len(data))


def _video_track(moov: _Box) -> _Box:
    for trak in moov.find(b"trak"):
        hdlr = trak.find(b"mdia", b"hdlr")
        if hdlr and hdlr[0].payload[8:12] == b"vide":
            return trak
    raise ValueError("the MP4 file has no video track")


def _set_duration(box: _Box, offset_v0: int, offset_v1: int, duration: int) -> None:
    """Write ``duration`` into a full box (mvhd, tkhd, mdhd) at its version's field offset."""
    p = bytearray(box.payload)
    if p[0] == 1:
        struct.pack_into(">Q", p, offset_v1, duration)
    else:
        struct.pack_into(">I", p, offset_v0, duration)
    box.payload = bytes(p)


def set_frame_times(path: str | Path, times, timescale: int = 90000, *, moov_first: bool = False) -> None:
    """Rewrite ``path`` in place so that its video frames are presented at ``times``.

    Parameters
    ----------
    path : str or Path
        An MP4 file with one video track and no composition offsets (e.g. from
        ``cv2.VideoWriter`` with ``mp4v``).
    times : array_like, shape (n_frames,)
        Presentation times (s), increasing, the first 0, each a whole number of ``1 / timescale``
        (checked: the file stores integer ticks). The last frame lasts as long as the one before.
    timescale : int
        Ticks per second of the video track's media clock (90000, the MPEG clock, as phones use).
    moov_first : bool
        Also move ``moov`` before ``mdat`` (right after ``ftyp``), as phones and FFmpeg's
        ``-movflags faststart`` write it: every chunk offset then moves.
    """
    path = Path(path)
    times = np.asarray(times, float)
    ticks = np.rint(times * timescale).astype(np.int64)
    if times.ndim != 1 or len(times) < 2 or ticks[0] != 0 or np.any(np.diff(ticks) <= 0):
        raise ValueError("times must be increasing, at least two, the first 0")
    if np.max(np.abs(ticks / timescale - times)) > 1e-9:
        raise ValueError(f"times must be whole multiples of 1/{timescale} s")
    deltas = np.append(np.diff(ticks), ticks[-1] - ticks[-2])
    data = path.read_bytes()
    top = _parse(data, 0, len(data))
    moov = next(b for b in top if b.kind == b"moov")
    trak = _video_track(moov)
    stbl = trak.find(b"mdia", b"minf", b"stbl")[0]
    if stbl.find(b"ctts"):
        raise ValueError("the video track has composition offsets (ctts): not supported")
    stsz = stbl.find(b"stsz")[0].payload
    n_samples = struct.unpack_from(">I", stsz, 8)[0]
    if n_samples != len(times):
        raise ValueError(f"the video track has {n_samples} frames, {len(times)} times given")
    # stts: run-length coded (count, delta) entries
    runs = []
    for d in deltas.tolist():
        if runs and runs[-1][1] == d:
            runs[-1][0] += 1
        else:
            runs.append([1, d])
    stts = stbl.find(b"stts")[0]
    stts.payload = struct.pack(">II", 0, len(runs)) + b"".join(struct.pack(">II", c, d) for c, d in runs)
    media_duration = int(deltas.sum())
    mdhd = trak.find(b"mdia", b"mdhd")[0]
    p = bytearray(mdhd.payload)
    struct.pack_into(">I", p, 20 if p[0] == 1 else 12, timescale)
    mdhd.payload = bytes(p)
    _set_duration(mdhd, 16, 24, media_duration)
    # durations in the movie's timescale (mvhd): the track header, the movie, the edit list
    mvhd = moov.find(b"mvhd")[0]
    movie_scale = struct.unpack_from(">I", mvhd.payload, 20 if mvhd.payload[0] == 1 else 12)[0]
    movie_duration = round(media_duration * movie_scale / timescale)
    _set_duration(trak.find(b"tkhd")[0], 20, 28, movie_duration)
    _set_duration(mvhd, 16, 24, movie_duration)
    for elst in trak.find(b"edts", b"elst"):
        p = bytearray(elst.payload)
        count = struct.unpack_from(">I", p, 4)[0]
        if count != 1:
            raise ValueError(f"the video track's edit list has {count} entries: not supported")
        if p[0] == 1:
            media_time = struct.unpack_from(">q", p, 16)[0]
            if media_time not in (0, -1):
                raise ValueError("the edit list starts the track late: not supported")
            struct.pack_into(">Q", p, 8, movie_duration)
        else:
            media_time = struct.unpack_from(">i", p, 12)[0]
            if media_time not in (0, -1):
                raise ValueError("the edit list starts the track late: not supported")
            struct.pack_into(">I", p, 8, movie_duration)
        elst.payload = bytes(p)
    # where each top-level box lands in the new file; the chunk offsets (of every track) follow
    # the box they point into
    if moov_first:
        top = [b for b in top if b.kind == b"ftyp"] + [moov] + \
            [b for b in top if b.kind != b"ftyp" and b is not moov]
    moves, pos = [], 0
    encoded = []
    for box in top:
        if box is moov:
            encoded.append(None)  # re-encoded below, once its chunk offsets are shifted
            size = len(box.encode())
        else:
            encoded.append(data[box.start:box.end])
            size = box.end - box.start
        moves.append((box.start, box.end, pos))
        pos += size

    def shifted(offset: int) -> int:
        for start, end, new in moves:
            if start <= offset < end:
                return offset - start + new
        raise ValueError(f"a chunk offset {offset} points outside every box")

    tables = [b for t in moov.find(b"trak") for b in t.find(b"mdia", b"minf", b"stbl")]
    for stco in (b for s in tables for b in s.find(b"stco")):
        count = struct.unpack_from(">I", stco.payload, 4)[0]
        offsets = struct.unpack_from(f">{count}I", stco.payload, 8)
        stco.payload = stco.payload[:8] + struct.pack(f">{count}I", *map(shifted, offsets))
    for co64 in (b for s in tables for b in s.find(b"co64")):
        count = struct.unpack_from(">I", co64.payload, 4)[0]
        offsets = struct.unpack_from(f">{count}Q", co64.payload, 8)
        co64.payload = co64.payload[:8] + struct.pack(f">{count}Q", *map(shifted, offsets))
    encoded = [moov.encode() if e is None else e for e in encoded]
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_bytes(b"".join(encoded))
    tmp.replace(path)

"""MCAP chunk codecs: bounded zstd and LZ4 decompression.

The codecs are driven through bounded APIs only (the size a zstd or LZ4 frame claims for
itself is never trusted), and a chunk's declared size is checked against a ceiling before
anything is allocated, so a decompression bomb costs at most its declared size.  The codec
packages (``zstandard``, ``lz4``) are imported only when a chunk needs them.
"""
from __future__ import annotations

from typing import Any

from inertia_ros.io.mcap_records import CodecMissingError, McapError

_CODEC_PACKAGES = {'zstd': ('zstandard', 'zstandard'), 'lz4': ('lz4.frame', 'lz4')}


#: Largest piece an LZ4 frame is decompressed in [bytes].
_PIECE = 16 << 20


#: Default ceiling on one chunk's uncompressed size [bytes]: a chunk declaring more, or a
#: compressed stream producing more than its chunk declares, is a damaged chunk (a
#: decompression bomb), never an allocation.
MAX_CHUNK_BYTES = 256 << 20


def decompress(compression: str, data: bytes | memoryview, size: int, *,
               limit: int = MAX_CHUNK_BYTES) -> bytes | bytearray:
    """Decompress a chunk's records, never producing more than ``size`` bytes.

    The declared size is checked against ``limit`` before anything is allocated, and the
    codecs are driven through bounded APIs (the size a zstd or LZ4 frame claims for itself
    is never trusted), so a decompression bomb costs at most ``size + 1`` bytes of memory.

    Parameters
    ----------
    compression : str
        ``''`` (none), ``'zstd'`` or ``'lz4'`` (LZ4 frame format).
    data : bytes
        The compressed records.
    size : int
        The uncompressed size the chunk declares [bytes].
    limit : int
        Largest uncompressed chunk accepted [bytes] (default :data:`MAX_CHUNK_BYTES`).

    Returns
    -------
    bytes or bytearray
        The uncompressed records, exactly ``size`` bytes long.

    Raises
    ------
    McapError
        Unknown compression, a declared size over ``limit``, a decompression failure, or
        output longer or shorter than declared.
    CodecMissingError
        The codec package (``zstandard`` or ``lz4``) is not installed.
    """
    check_chunk_size(compression, len(data), size, limit)
    if compression == '':
        return bytes(data)
    buf = bytearray(size + 1)
    view = memoryview(buf)
    try:
        decompress_into(compression, data, view, size)
    finally:
        view.release()
    del buf[size:]
    return buf


def check_chunk_size(compression: str, stored: int, size: int, limit: int) -> None:
    """Check a chunk's declared sizes before anything is allocated or read.

    Parameters
    ----------
    compression : str
        The chunk's compression (``''`` for none).
    stored : int
        Length of its (compressed) records field [bytes].
    size : int
        The uncompressed size the chunk declares [bytes].
    limit : int
        Largest uncompressed chunk accepted [bytes].

    Raises
    ------
    McapError
        A declared size over ``limit``, or an uncompressed chunk whose records field is not
        ``size`` bytes long.
    """
    if size > limit:
        raise McapError(f'chunk declares {size} uncompressed bytes, over the limit of '
                        f'{limit} (a decompression bomb or a damaged chunk header)')
    if compression == '' and stored != size:
        raise McapError(f'uncompressed chunk holds {stored} bytes, declared {size}')


def decompress_into(compression: str, data: bytes | memoryview, out: memoryview, size: int,
                    dctx: Any = None) -> None:
    """Decompress a chunk's records into ``out[:size]``, never writing past ``out[size]``.

    The bounded core of :func:`decompress` (which checks the declared size first, with
    :func:`check_chunk_size`): the output goes straight into the caller's buffer, e.g. a
    slot of a buffer holding several chunks back to back.

    Parameters
    ----------
    compression : str
        ``''``, ``'zstd'`` or ``'lz4'``.
    data : bytes
        The compressed records.
    out : memoryview
        Writable bytes, at least ``size + 1`` long (the extra byte detects output longer than
        declared) unless ``compression`` is ``''`` (then ``size``).
    size : int
        The uncompressed size the chunk declares [bytes].
    dctx : zstandard.ZstdDecompressor, optional
        A decompressor to reuse for zstd (a new one otherwise).

    Raises
    ------
    McapError
        Unknown compression, a decompression failure, or output longer or shorter than
        declared.
    CodecMissingError
        The codec package is not installed.
    """
    if compression == '':
        if len(data) != size:
            raise McapError(f'uncompressed chunk holds {len(data)} bytes, declared {size}')
        out[:size] = data
        return
    if compression not in ('zstd', 'lz4'):
        raise McapError(f'unsupported chunk compression {compression!r}')
    if len(out) < size + 1:
        raise ValueError(f'out: {len(out)} bytes, needs size + 1 = {size + 1}')
    codec = codec_module(compression)
    got = 0
    try:
        if compression == 'zstd':
            if dctx is None:
                dctx = codec.ZstdDecompressor()
            with dctx.stream_reader(data, read_across_frames=True) as r:
                while got <= size:
                    n = r.readinto(out[got:size + 1])
                    if not n:
                        break
                    got += n
        else:
            # in pieces: peak memory is the chunk plus one piece
            dec = codec.LZ4FrameDecompressor()
            piece = dec.decompress(bytes(data), max_length=min(size + 1, _PIECE))
            while True:
                out[got:got + len(piece)] = piece
                got += len(piece)
                if dec.eof or got > size or dec.needs_input:
                    break
                piece = dec.decompress(b'', max_length=min(size + 1 - got, _PIECE))
                if not piece:
                    break
    except Exception as exc:  # the codecs raise their own error types
        raise McapError(f'{compression} decompression failed: {exc}') from exc
    if got > size:
        raise McapError(f'{compression} data decompresses to more than the {size} bytes the '
                        'chunk declares (a decompression bomb or a damaged chunk)')
    if got != size:
        raise McapError(f'chunk decompressed to {got} bytes, declared {size}')


def codec_module(compression: str) -> Any:
    """Import the codec module of ``compression`` or raise :class:`CodecMissingError`."""
    import importlib

    module, package = _CODEC_PACKAGES[compression]
    try:
        return importlib.import_module(module)
    except ImportError:
        raise CodecMissingError(f'{compression}-compressed chunks need the Python package '
                                f'{package!r}: pip install {package}') from None

"""Memory guard: estimate the working set of a synthesis (a texture or a volume) before any
work, and refuse a size that would not fit (rather than swapping the machine to death or ending
in a MemoryError after minutes of work).

The limit is the memory the system reports available (/proc/meminfo MemAvailable, else
sysconf), lowered by the environment variable OSMAP_MEMORY_LIMIT (bytes, or with a K/M/G
suffix, e.g. 512M) when set.
"""

from __future__ import annotations

import os
import re

from osmap_cli.errors import OsmapError

ENV_LIMIT = "OSMAP_MEMORY_LIMIT"
BASE_BYTES = 200 * 2**20  # interpreter, NumPy, Numba and compiled kernels


# `--also`: the atlas' pyramids, features and k-NN tables, and the whole-copy take-back's
# per-pixel arrays; measured 115-200 MiB above a single-exemplar synthesis at 256 to 2048 px
# (three 128 px exemplars), so 128 MiB plus 24 bytes per pixel
ATLAS_BYTES = 128 * 2**20
ATLAS_PIXEL_BYTES = 24


def texture_bytes(width: int, height: int, channels: int, extra_channels: int = 0,
                  atlas: bool = False) -> int:
    """Peak working set of `osmap synth` for a WxH output: positions, the Jacobian field,
    copy-region labels per pixel, the output and its converted copy per channel, and
    EXTRA_CHANNELS of --with maps and --uv-out rendered beside it. Kept on the safe side (124
    bytes per pixel with 3 channels): the measured peak is about 37 bytes per pixel above the
    libraries at 1024 px and 63 at 4096 px (BENCHMARKS.md "Memory" and "Large outputs"), so at
    4096 px the estimate is about 1.7x the peak. `atlas`: several exemplars (--also) on top."""
    pixels = int(width) * int(height)
    total = BASE_BYTES + pixels * (88 + 12 * int(channels) + 12 * int(extra_channels))
    if atlas:
        total += ATLAS_BYTES + ATLAS_PIXEL_BYTES * pixels
    return total


def volume_bytes(shape, channels: int, feature_dims: int) -> int:
    """Peak working set of synthesize_solid + writing, for a (Z, Y, X) volume.

    Per voxel at the finest level: positions (3 axes x 2 x int32, old and new, plus int64
    upsampling temporaries), source (int32 x 3, old, new and int64 temporaries), match costs,
    appearance (old and new), the output voxels and one converted copy for writing."""
    voxels = int(shape[0]) * int(shape[1]) * int(shape[2])
    per_voxel = (24 * 2 + 48 * 2) + (12 * 2 + 24 * 3) + 12 + 8 * feature_dims + 12 * channels + 12
    return BASE_BYTES + voxels * per_voxel


# method structure on top of the optimisation: the slice families' guide channels, labels,
# identity colours, phase coverage, the particles' owner and distance, the colour matching's
# float64 copies; measured about 100 bytes a voxel above method osmap at 96^3
STRUCTURE_VOXEL_BYTES = 200


def structure_bytes(shape) -> int:
    """What method structure needs beyond volume_bytes for a (Z, Y, X) volume."""
    return int(shape[0]) * int(shape[1]) * int(shape[2]) * STRUCTURE_VOXEL_BYTES


def available_bytes() -> int:
    """MemAvailable from /proc/meminfo (else free physical pages), capped by OSMAP_MEMORY_LIMIT."""
    available = None
    try:
        with open("/proc/meminfo") as handle:
            for line in handle:
                if line.startswith("MemAvailable:"):
                    available = int(line.split()[1]) * 1024
                    break
    except OSError:
        pass
    if available is None:
        try:
            available = os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
        except (ValueError, OSError, AttributeError):
            available = 1 << 62
    text = os.environ.get(ENV_LIMIT, "").strip()
    if text:
        available = min(available, parse_bytes(text))
    return available


def parse_bytes(text: str) -> int:
    match = re.fullmatch(r"(\d+(?:\.\d+)?)\s*([kKmMgGtT]?)[iI]?[bB]?", text.strip())
    if match is None:
        raise OsmapError(f"{ENV_LIMIT}: {text!r} is not a size (examples: 800M, 4G, 1000000)")
    scale = {"": 1, "k": 2**10, "m": 2**20, "g": 2**30, "t": 2**40}[match.group(2).lower()]
    return int(float(match.group(1)) * scale)


def human(n: float) -> str:
    for unit in ("bytes", "KiB", "MiB", "GiB", "TiB"):
        if n < 1024 or unit == "TiB":
            return f"{n:.0f} {unit}" if unit == "bytes" else f"{n:.1f} {unit}"
        n /= 1024
    return f"{n:.1f} TiB"


def check_memory(need: int, what: str) -> int:
    """Raise OsmapError when NEED bytes (for WHAT, e.g. "a 512x512 texture") exceed the
    available memory; returns NEED."""
    have = available_bytes()
    if need > have:
        limited = f" (limited by {ENV_LIMIT})" if os.environ.get(ENV_LIMIT, "").strip() else ""
        raise OsmapError(f"{what} needs about {human(need)} of memory, but only "
                         f"{human(have)} is available{limited}; use a smaller --size")
    return need

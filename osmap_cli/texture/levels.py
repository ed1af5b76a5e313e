"""Pyramid level count: how many times the exemplars and the output can be halved."""

from __future__ import annotations

import math

# `wanted` 0: as many levels as halve the smallest exemplar side to about this many pixels,
# where the OS-Map organises the coarsest level (5 levels for a 256 px exemplar, 4 for 128 px).
COARSEST_EXEMPLAR = 16


def level_count(exemplar_shapes, out_shape, wanted: int, *, min_size: int,
                round_up: bool = True) -> int:
    """Pyramid levels: `wanted` (0: from the exemplar size, see COARSEST_EXEMPLAR), fewer when
    one more halving would take the smallest exemplar side (of `exemplar_shapes`, one (h, w)
    each) or the smallest output side (of `out_shape`, any dimensions) below `min_size`.

    round_up: a halved side is ceil(n / 2), the size `half_size` gives (synth); False: n // 2,
    a conservative estimate of it (solid).
    """
    smallest = min(min(s) for s in exemplar_shapes)
    side = min(out_shape)
    if wanted == 0:
        ratio = max(smallest, 1) / COARSEST_EXEMPLAR
        wanted = max(1, round(math.log2(ratio)) + 1) if ratio > 1 else 1

    def halve(n: int) -> int:
        return max(1, (n + 1) // 2) if round_up else n // 2

    levels = 1
    while levels < wanted:
        smallest, side = halve(smallest), halve(side)
        if smallest < min_size or side < min_size:
            break
        levels += 1
    return levels

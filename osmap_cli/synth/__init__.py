"""2D texture synthesis: read -> organise (OS-Map) -> refine -> render -> write.

>>> from osmap_cli.synth import SynthOptions, synthesize
>>> result = synthesize(exemplar_pixels, SynthOptions(width=256, height=256, seed=1))
>>> result.pixels.shape, result.positions.shape
((256, 256, 3), (256, 256, 2))

`SynthOptions` is cheap to import; the pipeline (Numba kernels) loads on first use of
`synthesize` / `SynthResult`, so option validation and `--help` stay fast.
"""

from typing import TYPE_CHECKING

from osmap_cli.synth.options import SynthOptions

if TYPE_CHECKING:  # loaded on first use by __getattr__ below
    from osmap_cli.synth.pipeline import SynthResult, synthesize

__all__ = ["SynthOptions", "SynthResult", "synthesize"]


def __getattr__(name):
    if name in ("SynthResult", "synthesize"):
        from osmap_cli.synth import pipeline
        return getattr(pipeline, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")

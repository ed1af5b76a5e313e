"""One `osmap solid --analyse` job: an exemplar (or one --x/--y/--z set) -> what structure the
structure method reads from it (printed) and its segmentation beside it as a picture.

    read (the exemplars) -> check (channels, size) -> compute (the analysis and the model)
    -> stage (the picture, one transaction) -> commit
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from osmap_cli.solid.job import ExemplarSetJob

__all__ = ["AnalyseJob", "picture_name"]


def picture_name(exemplar: str) -> str:
    """The picture's default path: beside the exemplar, STEM_segmentation.png."""
    import os

    stem = os.path.splitext(exemplar)[0]
    return f"{stem}_segmentation.png"


@dataclass(frozen=True)
class AnalyseJob(ExemplarSetJob):
    """The analysis of one exemplar or --x/--y/--z set and where its picture goes."""

    index: int
    exemplar: str
    files: tuple  # (x, y, z) exemplars, or one for all three families
    output: str  # the segmentation picture (.png)
    options: object  # SolidOptions (validated): structure, phases, tileable, seed
    replace: bool = True
    refused: str | None = None
    progress: bool = False

    @property
    def outputs(self) -> list[str]:
        return [self.output]

    def describe(self) -> dict:
        return self.exemplar_record(options={
            k: v for k, v in dataclasses.asdict(self.options).items()
            if k in ("structure", "phases", "tileable", "seed")})

    def check(self, images) -> None:
        from osmap_cli.image_formats import output_format

        super().check(images)
        output_format(self.output, 8, 3)

    def compute(self, images):
        import numpy as np

        from osmap_cli.solid.structure.method import plan

        distinct = [im.pixels for im in images]
        ex_of_axis = np.zeros(3, np.int64) if len(distinct) == 1 else np.arange(3)
        opts = self.options
        return plan(distinct, ex_of_axis, opts.structure, opts.phases, opts.seed, opts.tileable)

    def stage(self, outputs, images, found) -> tuple[str, list[str]]:
        import numpy as np

        from osmap_cli.imageio import encode_image
        from osmap_cli.solid.structure.picture import segmentation_picture

        pictures = [segmentation_picture(im, an) for im, an in zip(found.images, found.analyses)]
        width = max(p.shape[1] for p in pictures)
        rows = [np.pad(p, ((0, 4), (0, width - p.shape[1]), (0, 0)), constant_values=1.0)
                for p in pictures]
        picture = np.concatenate(rows, 0)[:-4]
        outputs.stage(self.output, lambda temp: encode_image(temp, picture, 8,
                                                             name=self.output))
        return "\n".join([*found.report(), f"wrote {self.output}: the segmentation"]), []

"""A job double for batch tests: one exemplar name in, one text file out, no images, so a
batch of them runs in milliseconds. Subclasses add what they do in read() and compute()."""

from __future__ import annotations

import dataclasses

from osmap_cli.batch import Job


@dataclasses.dataclass(frozen=True)
class FileJob(Job):
    exemplar: str
    target: str
    replace: bool = True
    refused: str | None = None
    progress: bool = False

    @property
    def outputs(self) -> list[str]:
        return [self.target]

    def describe(self) -> dict:
        return {"input": self.exemplar, "outputs": self.outputs}

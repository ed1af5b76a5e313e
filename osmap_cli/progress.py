"""A tqdm progress bar on stderr for the synthesis pipeline's ``progress`` callback.

The pipeline calls ``progress(fraction)`` with the fraction of the total work done *since the
previous call* (the increments add up to about 1). :class:`ProgressBar` is that callable; it
draws nothing unless it is enabled, which the CLI does only when stderr is a terminal and
``--quiet`` is not given.

>>> with ProgressBar(enabled=sys.stderr.isatty(), desc="synth") as progress:
...     synthesize(pixels, options, progress=progress)
"""

from __future__ import annotations

import sys

__all__ = ["ProgressBar", "latch_interrupts", "reset_interrupt"]

_STEPS = 1000  # bar resolution: 0.1 %
_interrupted: list = [None]  # the exception a latched signal raises again at the next step

_STOP_SIGNALS = ("SIGINT", "SIGTERM", "SIGHUP")


def _stop_exception(signum: int) -> BaseException:
    import signal

    if signum == signal.SIGINT:
        return KeyboardInterrupt()
    from osmap_cli.errors import Terminated

    return Terminated(signum)


def latch_interrupts() -> None:
    """Make Ctrl-C, SIGTERM and SIGHUP stick: the handler raises (KeyboardInterrupt, or
    osmap_cli.errors.Terminated) as usual and also records the signal, so that the next
    progress call raises again: a signal that lands inside a library which swallows it (Numba
    compiling a kernel on the first run) still stops the job there. Call from the main
    thread."""
    import signal

    def handler(signum, frame):
        _interrupted[0] = signum
        raise _stop_exception(signum)

    for name in _STOP_SIGNALS:
        if hasattr(signal, name):
            signal.signal(getattr(signal, name), handler)


def reset_interrupt() -> None:
    """Forget a latched signal (for callers that run several commands in one process)."""
    _interrupted[0] = None


class ProgressBar:
    """Callable progress sink: ``bar(fraction)`` advances by ``fraction`` of the whole job."""

    def __init__(self, enabled: bool, desc: str = "", file=None):
        self.done = 0.0
        self._bar = None
        if enabled:
            from tqdm import tqdm  # imported only when a bar is drawn

            self._bar = tqdm(
                total=_STEPS,
                desc=desc,
                file=file if file is not None else sys.stderr,
                leave=False,
                dynamic_ncols=True,
                bar_format="{desc}: {percentage:3.0f}%|{bar}| [{elapsed}<{remaining}]",
            )

    def __call__(self, fraction: float) -> None:
        if _interrupted[0] is not None:
            raise _stop_exception(_interrupted[0])
        fraction = float(fraction)
        if not fraction > 0.0:  # also ignores NaN
            return
        self.done = min(1.0, self.done + fraction)
        if self._bar is not None:
            target = int(round(self.done * _STEPS))
            if target > self._bar.n:
                self._bar.update(target - self._bar.n)

    def close(self) -> None:
        """Remove the bar from the terminal (it is not left behind)."""
        if self._bar is not None:
            self._bar.close()
            self._bar = None

    def __enter__(self) -> ProgressBar:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

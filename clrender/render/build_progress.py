"""Progress while a cold pipeline builds its programs (clrender/progress.py): the programs of the
passes a frame runs, built up front (count and ETA), then each pass's first launch (where PoCL
compiles its kernels). A warm pipeline reports nothing."""
from __future__ import annotations

from contextlib import contextmanager, nullcontext

from clrender import progress
from clrender.device.core import lazy_kernels


class BuildProgress:
    def __init__(self, device):
        self.device = device
        self.launched: set = set()   # passes launched at least once (their kernels compiled)
        self.built: set = set()      # passes whose programs are all built

    def stage(self, running: list):
        """A progress stage for a frame that builds programs of the `running` passes, or a null
        context (yielding None) when everything is built. Passes that make their programs on the
        way (builds_on_publish: the shadow maps' stages) are never walked here, so a warm frame
        walks nothing; their programs are built in the loop, or by their first launch."""
        running = [p for p in running if not p.builds_on_publish and p not in self.built]
        unbuilt = {p: [k.spec for k in lazy_kernels(p) if not k.built] for p in running}
        self.built.update(p for p, specs in unbuilt.items() if not specs)    # programs are never unbuilt
        specs = [s for p_specs in unbuilt.values() for s in p_specs]
        if not specs:
            return nullcontext()

        @contextmanager
        def stage():
            first = [p for p in running if p not in self.launched]
            with progress.stage("building OpenCL programs", len(first), self.device.name) as s:
                self.device.build(specs)
                yield s
        return stage()

    def before_run(self, p, stage) -> None:
        """In a building frame: the programs `p` made on the way (publish) are built now."""
        if stage is not None:
            self.device.build(k.spec for k in lazy_kernels(p))

    def after_run(self, p, stage) -> None:
        if stage is not None and p not in self.launched and not p.builds_on_publish:
            self.launched.add(p)
            stage.advance(f"first launch: {p.name}")

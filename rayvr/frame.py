"""The frame graph: passes declare what they read and write and when they are needed; the graph
keeps only the passes the requested output depends on, orders them by their data edges, and
times each with a GL timer query.

A pass (rayvr/passes/) subclasses `Pass`:
    name     unique name, also the key of its GPU time in `Frame.timings`
    reads    resource names it consumes
    writes   resource names it produces
    needed(plan)   False when this plan (effects in use, view, settings) has no use for it
    setup(gl)      build programs once
    execute(fc)    record the GL work for one frame

Scenes whose materials are all `raster` get G-buffer -> shade -> resolve and nothing else: the
pass that builds a BVH or traces rays simply declares `needed()` False for them.

A pass may read and write the same resource (the ray-traced effects read "hdr" and overwrite
their own pixels of it): each read is served by the latest needed writer registered *before* the
reading pass, and the frame's output by the last writer of all, so such passes chain in
registration order.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import moderngl


@dataclass
class FramePlan:
    """What this frame must produce and from what: decides which passes run."""

    effects: frozenset  # effect names the scene's materials use
    view: str = "color"  # "color" or a debug view name (rayvr/passes/debug_view.py)
    layers: int = 2
    layer_mode: str = "vertex"  # how the G-buffer reaches its layers: vertex | geometry | multiview | passes
    output: str = "ldr"
    primary: str = "raster"  # primary visibility: "raster" (visibility pass) or "rays" (BVH)



class Pass:
    name = "pass"
    reads: tuple = ()
    writes: tuple = ()

    def needed(self, plan: FramePlan) -> bool:
        return True

    def setup(self, gl, plan: FramePlan) -> None:
        pass

    def execute(self, fc) -> None:  # fc: renderer.FrameContext
        raise NotImplementedError

    def release(self) -> None:
        pass


class GraphError(RuntimeError):
    pass


def schedule(passes: list[Pass], plan: FramePlan) -> list[Pass]:
    """The passes `plan.output` depends on, in dependency order.

    A resource read by a pass is produced by the latest needed pass registered before it that
    writes it (the output: by the last writer); passes nobody's output depends on are dropped."""
    candidates = [p for p in passes if p.needed(plan)]
    writers: dict[str, list[int]] = {}
    for i, p in enumerate(candidates):
        for r in p.writes:
            writers.setdefault(r, []).append(i)
    chosen: list[Pass] = []
    visiting: set[int] = set()

    def visit(resource: str, before: int, chain: tuple) -> None:
        earlier = [i for i in writers.get(resource, ()) if i < before]
        if not earlier:
            raise GraphError(f"no pass produces {resource!r} (needed by {' <- '.join(chain) or 'the frame'})")
        i = earlier[-1]
        p = candidates[i]
        if p in chosen:
            return
        if i in visiting:
            raise GraphError(f"cycle in the frame graph at pass {p.name!r}")
        visiting.add(i)
        for r in p.reads:
            visit(r, i, chain + (p.name,))
        visiting.discard(i)
        chosen.append(p)

    visit(plan.output, len(candidates), ())
    return chosen


@dataclass
class PassTimer:
    """GL timer queries, one per pass and slot. Two slots alternate frame by frame, so a frame's
    times can be read after the next frame has been recorded (reading waits for the GPU)."""

    ctx: moderngl.Context
    queries: dict = field(default_factory=dict)
    slot: int = 0

    def next_frame(self) -> None:
        self.slot ^= 1

    def run(self, name: str, fn) -> None:
        key = (self.slot, name)
        q = self.queries.get(key)
        if q is None:
            q = self.queries[key] = self.ctx.query(time=True)
        with q:
            fn()

    def read_ms(self, names, slot: int | None = None) -> dict:
        slot = self.slot if slot is None else slot
        return {n: self.queries[(slot, n)].elapsed / 1e6 for n in names if (slot, n) in self.queries}

"""The frame graph's compiler on its own (no GL): order from data edges, composers between the
writer and the readers, pruning, reasons, and the errors a wrong graph gets."""
from __future__ import annotations

import pytest

from rayvr.frame.graph import Buffer, FramePlan, GraphError, Pass, Texture, compile_graph, compose, read, write

PLAN = FramePlan(effects=frozenset({"raster"}))


def node(name, reads=(), writes=(), composes=(), why=""):
    class P(Pass):
        def why(self, plan):
            return why

        def io(self, plan):
            return ([read(r) for r in reads] + [write(w, Texture("rgba16f")) for w in writes]
                    + [compose(c) for c in composes])
    p = P()
    p.name = name
    return p


def test_order_follows_data_edges_not_registration():
    passes = [node("tonemap", reads=["hdr"], writes=["ldr"]), node("fx_b", reads=["g"], composes=["hdr"]),
              node("shade", reads=["g"], writes=["hdr"]), node("fx_a", reads=["g"], composes=["hdr"]),
              node("gbuffer", writes=["g"])]
    g = compile_graph(passes, PLAN)
    names = g.pass_names
    assert names.index("gbuffer") < names.index("shade") < names.index("fx_a") < names.index("tonemap")
    assert names.index("shade") < names.index("fx_b") < names.index("tonemap")  # composers after the writer
    assert set(g.types) == {"g", "hdr", "ldr"}
    assert g.reasons["shade"] == "feeds fx_b, fx_a, tonemap"


def test_passes_nobody_reads_are_dropped_and_unavailable_ones_ignored():
    passes = [node("gbuffer", writes=["g"]), node("bvh", writes=["bvh"]), node("trace", reads=["bvh", "g"], writes=["x"]),
              node("shade", reads=["g"], writes=["ldr"]), node("never", writes=["ldr"], why=None)]
    g = compile_graph(passes, PLAN)
    assert g.pass_names == ["gbuffer", "shade"]
    assert g.reasons["shade"] == "makes the frame's output" and g.reasons["gbuffer"] == "feeds shade"


def test_errors_name_the_resource_and_passes():
    with pytest.raises(GraphError, match="no pass produces 'g' \\(read by shade\\)"):
        compile_graph([node("shade", reads=["g"], writes=["ldr"])], PLAN)
    with pytest.raises(GraphError, match="'ldr' is written by both 'a' and 'b'"):
        compile_graph([node("a", writes=["ldr"]), node("b", writes=["ldr"])], PLAN)
    with pytest.raises(GraphError, match="cycle in the frame graph"):
        compile_graph([node("a", reads=["y"], writes=["x"]), node("b", reads=["x"], writes=["y"]),
                       node("out", reads=["x"], writes=["ldr"])], PLAN)
    with pytest.raises(GraphError, match="no pass produces 'ldr'"):
        compile_graph([node("a", writes=["x"])], PLAN)


def test_buffer_sizes_follow_their_rule_and_describe_prints_them():
    from rayvr.frame.graph import Sizing

    class Lists(Pass):
        name = "lists"

        def io(self, plan):
            return [write("ldr", Buffer(lambda s: 4 * s.pixels, "4 B per eye pixel"))]
    g = compile_graph([Lists()], PLAN)
    text = g.describe(Sizing((64, 32), 2))
    assert "1. lists" in text and "ldr" in text and "0.02 MiB" in text and "4 B per eye pixel" in text
    assert g.dot().startswith("digraph") and '"lists" -> "res:ldr";' in g.dot()

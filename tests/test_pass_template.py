"""The pass template (clrender/passes/_template.py <-> kernels/_template.cl) is a working pass:
built and run on the default device through the pass contract, exact against NumPy."""
from __future__ import annotations

import numpy as np
import pyopencl.array as cla

import clrender
from clrender.device.core import Device, kernels_dir
from clrender.passes.base import Resources
from clrender.passes._template import REC709, TemplatePass


def test_template_pass_computes_luminance_exactly(device):
    dev = Device.get(device.id)
    config = clrender.RenderConfig()
    w, h = 37, 23                                   # not a multiple of the work-group: ids past W·H return
    assert TemplatePass.runs(config)
    p = TemplatePass(dev, config)
    p.allocate(w, h)
    assert sum(TemplatePass.buffer_bytes(w, h, config).values()) == p.luminance.nbytes
    color = np.random.default_rng(3).uniform(0, 4, (3, h, w)).astype(np.float32)
    res = Resources(buffers={"color": cla.to_device(dev.queue, color.reshape(-1))}, values={"width": w, "height": h})
    assert all(name in res for name in p.inputs)
    p.publish(res)
    assert all(name in res for name in p.outputs)
    p.run(res)
    got = res["luminance"].get(queue=dev.queue).reshape(h, w)
    r, g, b = color
    wr, wg, wb = (np.float32(v) for v in REC709)
    expected = (wr * r + wg * g) + wb * b          # float32, the kernel's order, no contraction
    np.testing.assert_array_equal(got, expected)


def test_template_kernel_compiles_on_its_own_and_documents_itself(device):
    """No defines: every option has a default; the opening comment names algorithm, buffers and
    work-groups (the house rule for kernels/*.cl)."""
    dev = Device.get(device.id)
    dev.program("_template.cl")
    head = (kernels_dir() / "_template.cl").read_text().split("*/")[0]
    for word in ("Algorithm:", "Buffers:", "Work-groups:"):
        assert word in head

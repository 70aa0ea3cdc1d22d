"""Independent reference implementations the OpenCL kernels are tested against.

``reference.raster`` implements docs/raster_contract.md in pure NumPy (float32 step by step).
"""

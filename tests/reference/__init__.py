"""Independent reference implementations the OpenCL kernels are tested against.

``reference.raster`` implements docs/raster_contract.md in pure NumPy (float32 step by step).
``reference.gltf_reader`` reads glTF files with json + numpy only, for the loader tests.
"""

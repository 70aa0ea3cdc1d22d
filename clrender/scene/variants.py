"""Material variants (glTF KHR_materials_variants): named sets of per-mesh material replacements that
`Scene.set_variant` switches between.

A `MaterialVariants` record holds, for every Scene mesh (a glTF primitive drawn by one node or one
GPU instance) that some variant maps, the material it has with no variant active (`defaults`), and
per variant the meshes it maps and their materials. Switching rewrites `Scene.triangle_material`
for exactly the triangles of the meshes the old and the new variant map (a mesh neither maps keeps
its triangles' materials, edits included), into a NEW array: the renderer's upload cache compares
arrays by identity (clrender/render/scene_upload.py `_fingerprint`), so the next frame uploads the
scene again, and a Frame already rendered keeps the array it was rendered with.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np

from clrender.errors import SceneError


@dataclass(frozen=True, eq=False)
class MaterialVariants:
    names: tuple                # variant names, file order (a name given twice selects its first variant)
    meshes: np.ndarray          # (K,) int32: every mesh some variant maps, ascending
    defaults: np.ndarray        # (K,) int32: their materials with no variant active
    mappings: tuple             # per variant: ((k,) int32 meshes ascending, (k,) int32 materials)

    def __post_init__(self):
        object.__setattr__(self, "names", tuple(str(n) for n in self.names))
        object.__setattr__(self, "meshes", np.asarray(self.meshes, np.int32).reshape(-1))
        object.__setattr__(self, "defaults", np.asarray(self.defaults, np.int32).reshape(-1))
        object.__setattr__(self, "mappings", tuple((np.asarray(m, np.int32).reshape(-1),
                                                    np.asarray(t, np.int32).reshape(-1)) for m, t in self.mappings))
        if len(self.mappings) != len(self.names) or self.meshes.shape != self.defaults.shape:
            raise SceneError("material variants: one mapping per name and one default per mapped mesh are needed")

    @classmethod
    def from_meshes(cls, names, mesh_maps: dict, mesh_defaults: dict) -> Optional["MaterialVariants"]:
        """From {mesh: {variant index: material}} and {mesh: default material}; None without names."""
        if not names:
            return None
        meshes = sorted(mesh_maps)
        per_variant = [([m for m in meshes if v in mesh_maps[m]], [mesh_maps[m][v] for m in meshes
                                                                     if v in mesh_maps[m]])
                       for v in range(len(names))]
        return cls(tuple(names), np.array(meshes, np.int32), np.array([mesh_defaults[m] for m in meshes], np.int32),
                   tuple(per_variant))

    def index(self, name: str, where: str) -> int:
        """The variant index of `name`; SceneError (one line, listing the names) when there is none."""
        if isinstance(name, str) and name in self.names:
            return self.names.index(name)
        listed = ", ".join(repr(n) for n in self.names) or "none"
        raise SceneError(f"{where}: no material variant {name!r} (variants: {listed})")

    def check(self, mesh_count: int, material_count: int, where: str) -> None:
        """SceneError when a mapping names a mesh or a material the scene does not have."""
        for meshes, materials in [(self.meshes, self.defaults), *self.mappings]:
            if meshes.size and (meshes.min() < 0 or meshes.max() >= mesh_count):
                raise SceneError(f"{where}: a material variant maps a mesh that does not exist ({mesh_count} meshes)")
            if materials.size and (materials.min() < 0 or materials.max() >= material_count):
                raise SceneError(f"{where}: a material variant uses a material that does not exist "
                                 f"({material_count} materials)")

    def switch(self, triangle_mesh: np.ndarray, triangle_material: np.ndarray, old: Optional[int],
               new: Optional[int]) -> np.ndarray:
        """A new triangle_material: the meshes variant `old` mapped back to their defaults, then the
        meshes variant `new` maps to its materials (None: no variant)."""
        lut = np.full(int(self.meshes.max()) + 1 if self.meshes.size else 0, -1, np.int64)
        if old is not None:
            meshes = self.mappings[old][0]
            lut[meshes] = self.defaults[np.searchsorted(self.meshes, meshes)]
        if new is not None:
            meshes, materials = self.mappings[new]
            lut[meshes] = materials
        out = np.array(triangle_material, np.int32, copy=True)
        if not lut.size:
            return out
        tm = np.asarray(triangle_mesh)
        inside = tm < len(lut)
        per = np.full(len(tm), -1, np.int64)
        per[inside] = lut[tm[inside]]
        mapped = per >= 0
        out[mapped] = per[mapped]
        return out

"""Scene model: one flattened, world-space triangle soup with materials and textures.

Every loader (glTF, OBJ/MTL, PLY, STL, TOML) produces this one representation.
Triangle indices are load order and are what `Frame.triangle_id` reports; the
scene never reorders or drops triangles, so ids stay stable. Vertex positions must be finite
and within ±MAX_COORDINATE (`check_positions`: a SceneError naming the array and the vertex,
from every loader and from Scene construction, upload and set_transform); the setup kernel still
drops and counts triangles that only the device's posing (skins, morph targets) makes invalid.

Objects (`Scene.objects`, what `Frame.object_id` indexes): one record per drawn instance. A glTF
node with a mesh is one object (two nodes sharing a mesh are two), made of that mesh's
primitives, which are the scene's meshes (`mesh_names`, pieces); an OBJ o/g group (a file
without groups: the file), a PLY/STL file and a TOML [[mesh]] entry are one each. `mesh_object`
maps each mesh to its object, so a triangle's object is mesh_object[triangle_mesh[t]].

Beside it: clrender.scene.geometry (the coordinate checks, vertex normals) and clrender.scene.motion
(`set_transform` and `pose`, a base class of Scene).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Optional

import numpy as np

from clrender.abi import structs
from clrender.scene.camera import Camera
from clrender.errors import SceneError
from clrender.scene.geometry import check_positions, vertex_normals
from clrender.scene.motion import SceneMotion
from clrender.scene.variants import MaterialVariants
from clrender.scene.material import (
    ALPHA_MODES, LUMA, TEXTURE_SLOTS, Material, UVTransform, metallic_roughness_to_blinn_phong)

if TYPE_CHECKING:
    from clrender.scene.deform import Deformation
    from clrender.scene.environment import Environment

WRAP_MODES = ("repeat", "clamp", "mirror")


@dataclass(frozen=True)
class ParticleSystem:
    """Animated lights occupying `lights[first:first + count]` (kernels/particles.cl)."""
    first: int
    count: int
    seed: int
    lo: tuple
    hi: tuple
    speed: float
    life_min: float
    life_max: float
    radius_min: float
    radius_max: float
    intensity: float


SHADOW_MAP_SIZES = (16, 8192)      # inclusive range of a shadow map's side in texels

def check_shadow_map_size(size) -> int:
    if not (isinstance(size, (int, np.integer)) and not isinstance(size, bool)
            and SHADOW_MAP_SIZES[0] <= size <= SHADOW_MAP_SIZES[1]):
        raise SceneError(f"shadow_map_size must be an integer in [{SHADOW_MAP_SIZES[0]}, {SHADOW_MAP_SIZES[1]}], "
                         f"got {size!r}")
    return int(size)


@dataclass(frozen=True)
class Sun:
    """A directional light: `direction` is the way the light travels (unit), `color` its
    linear RGB radiance (intensity included); it lights every pixel with N·L, no falloff."""
    direction: tuple
    color: tuple
    shadow: bool = True
    shadow_map_size: int = 2048

    def __post_init__(self):
        d = np.asarray(self.direction, np.float64).reshape(-1)
        c = np.asarray(self.color, np.float64).reshape(-1)
        norm = float(np.linalg.norm(d)) if d.shape == (3,) else 0.0
        if not (np.isfinite(norm) and norm > 0):
            raise SceneError(f"sun direction must be a non-zero finite 3-vector, got {self.direction!r}")
        if c.shape != (3,) or not np.isfinite(c).all() or (c < 0).any():
            raise SceneError(f"sun color must be 3 finite non-negative numbers, got {self.color!r}")
        if not isinstance(self.shadow, (bool, np.bool_)):
            raise SceneError(f"sun shadow must be True or False, got {self.shadow!r}")
        object.__setattr__(self, "direction", tuple(float(v) for v in d / norm))
        object.__setattr__(self, "color", tuple(float(v) for v in c))
        object.__setattr__(self, "shadow", bool(self.shadow))
        object.__setattr__(self, "shadow_map_size", check_shadow_map_size(self.shadow_map_size))


@dataclass(frozen=True, eq=False)   # identity semantics: cached mip chains key on it
class Texture:
    """RGBA8 image, row 0 at the top (as image files store it); color data is sRGB-encoded."""
    name: str
    rgba: np.ndarray            # (H, W, 4) uint8
    wrap_s: str = "repeat"
    wrap_t: str = "repeat"
    srgb: bool = True

    def __post_init__(self):
        rgba = np.ascontiguousarray(self.rgba, dtype=np.uint8)
        if rgba.ndim != 3 or rgba.shape[2] != 4 or rgba.shape[0] < 1 or rgba.shape[1] < 1:
            raise SceneError(f"texture {self.name!r}: expected an (H, W, 4) uint8 image, got shape {self.rgba.shape}")
        if self.wrap_s not in WRAP_MODES or self.wrap_t not in WRAP_MODES:
            raise SceneError(f"texture {self.name!r}: wrap modes must be in {WRAP_MODES}")
        object.__setattr__(self, "rgba", rgba)


@dataclass(frozen=True)
class SceneObject:
    """One drawn instance: `name` (the glTF node's, the OBJ group's, the TOML entry's), the name
    of the `mesh` it draws, its `path` from the root ("parent/child" node names for glTF; past 63
    levels the middle is shortened to "...<k nodes>...", see loaders/gltf/assemble.py PATH_HEAD) and its
    `extras`: the glTF node's (any JSON value: semantic labels travel here) or the TOML entry's
    `extras` table; None elsewhere. `volume_scale`: how its transform scales lengths, |det M|^(1/3) of
    its world matrix's 3x3 (glTF: KHR_materials_volume's thickness is in mesh units and the node's
    transform applies to it); 1 where the loader does not know it."""
    name: str
    mesh: str
    path: str
    extras: object = None
    node: Optional[int] = None          # glTF node index
    volume_scale: float = 1.0

    def __post_init__(self):
        v = self.volume_scale
        if not (isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool)
                and np.isfinite(v) and v > 0):
            raise SceneError(f"object {self.name!r}: volume_scale must be a finite number > 0, got {v!r}")
        object.__setattr__(self, "volume_scale", float(v))


@dataclass
class Scene(SceneMotion):
    positions: np.ndarray                       # (V, 3) float32, world space
    normals: np.ndarray                         # (V, 3) float32, unit
    uvs: np.ndarray                             # (V, 2) float32, glTF convention (v down the image)
    triangles: np.ndarray                       # (T, 3) int32
    triangle_material: np.ndarray               # (T,) int32 index into materials
    materials: list[Material] = field(default_factory=lambda: [Material()])
    textures: list[Texture] = field(default_factory=list)
    mesh_names: list[str] = field(default_factory=lambda: ["mesh"])
    triangle_mesh: Optional[np.ndarray] = None  # (T,) int32 index into mesh_names
    triangle_face: Optional[np.ndarray] = None  # (T,) int32 face index inside that mesh
    camera: Optional[Camera] = None
    source: str = "<arrays>"
    settings: dict = field(default_factory=dict)  # render settings from a scene file
    lights: np.ndarray = field(default_factory=lambda: np.zeros(0, structs.light_dtype))
    ambient: float = 0.03                       # ambient term: ambient · albedo
    particle_systems: list = field(default_factory=list)   # ParticleSystem: animated slices of `lights`
    sun: Optional["Sun"] = None                 # the directional light (set_sun)
    previous_positions: Optional[np.ndarray] = None   # (V, 3) at the previous frame (set_transform); None: static
    colors: Optional[np.ndarray] = None         # (V, 4) float32 linear RGBA vertex colours (COLOR_0); None: white
    tangents: Optional[np.ndarray] = None       # (V, 4) float32 world-space unit tangent + handedness w (±1);
                                                # None: generated at upload if a material has a normal map
    extra_uvs: Optional[np.ndarray] = None      # (K, V, 2) float32: TEXCOORD_1 .. TEXCOORD_K; None: K = 0
    animation: Optional[object] = None          # clrender.scene.animation.Animation (glTF animations); None: static
    environment: Optional["Environment"] = None  # HDR image-based lighting (set_environment); when set,
                                                # the constant `ambient` term is not added
    deformation: Optional["Deformation"] = None  # skins and morph targets (clrender.scene.deform): posed on the
                                                # device; positions/normals/tangents hold the load pose
    objects: list = field(default_factory=list)  # SceneObject per drawn instance (module doc); empty:
                                                # one per mesh, named after it
    mesh_object: Optional[np.ndarray] = None    # (len(mesh_names),) int32 index into objects
    source_files: tuple = ()                    # resolved Paths load_scene read (the scene file, its buffers,
                                                # textures, MTL, TOML meshes, environment): outputs must not be one
    material_variants: Optional[MaterialVariants] = None  # glTF KHR_materials_variants (set_variant); None: none
    cameras: list = field(default_factory=list)  # (name, Camera) per camera the file defines, in order (glTF:
                                                # each usable camera node in traversal order; TOML: [camera], else
                                                # its mesh files'); `camera` is the first at load. Rest pose:
                                                # animations move `camera` only. Empty: arrays, OBJ, PLY, STL

    def __post_init__(self):
        self.positions = np.ascontiguousarray(self.positions, dtype=np.float32).reshape(-1, 3)
        self.normals = np.ascontiguousarray(self.normals, dtype=np.float32).reshape(-1, 3)
        self.uvs = np.ascontiguousarray(self.uvs, dtype=np.float32).reshape(-1, 2)
        self.triangles = np.ascontiguousarray(self.triangles, dtype=np.int32).reshape(-1, 3)
        self.triangle_material = np.ascontiguousarray(self.triangle_material, dtype=np.int32).reshape(-1)
        self.lights = np.ascontiguousarray(self.lights, dtype=structs.light_dtype).reshape(-1)
        n_tri = len(self.triangles)
        if self.triangle_mesh is None:
            self.triangle_mesh = np.zeros(n_tri, np.int32)
        if self.triangle_face is None:
            self.triangle_face = np.arange(n_tri, dtype=np.int32)
        if self.mesh_object is None:
            if not self.objects:
                self.objects = [SceneObject(n, n, n) for n in self.mesh_names]
            self.mesh_object = np.arange(len(self.mesh_names), dtype=np.int32)
        self.mesh_object = np.ascontiguousarray(self.mesh_object, dtype=np.int32).reshape(-1)
        if self.previous_positions is not None:
            self.previous_positions = np.ascontiguousarray(self.previous_positions, dtype=np.float32)
        if self.colors is not None:
            self.colors = np.ascontiguousarray(self.colors, dtype=np.float32)
        if self.tangents is not None:
            self.tangents = np.ascontiguousarray(self.tangents, dtype=np.float32)
        if self.extra_uvs is not None:
            self.extra_uvs = np.ascontiguousarray(self.extra_uvs, dtype=np.float32)
        self._rest_poses: dict = {}             # mesh index -> its geometry before any set_transform
        self._rest_tangents: dict = {}          # mesh index -> its tangents before any set_transform
        self._variant: Optional[int] = None     # the active material variant's index (set_variant)
        self.validate()

    # -- construction -------------------------------------------------------------------------
    @classmethod
    def from_arrays(cls, vertices, faces, normals=None, uvs=None, material: Optional[Material] = None,
                    camera: Optional[Camera] = None) -> "Scene":
        """A scene from plain arrays. The default material is white and double-sided."""
        try:
            positions = np.asarray(vertices, dtype=np.float32)
            triangles = np.asarray(faces)
        except (TypeError, ValueError) as exc:
            raise SceneError(f"<arrays>: vertices/faces are not numeric arrays ({exc})") from None
        if positions.ndim != 2 or positions.shape[1] != 3:
            raise SceneError(f"<arrays>: vertices must have shape (V, 3), got {positions.shape}")
        check_positions(positions, "<arrays>", "vertices")       # before normals are computed from them
        if triangles.size and not np.issubdtype(triangles.dtype, np.integer):
            raise SceneError(f"<arrays>: faces must be integers, got dtype {triangles.dtype}")
        triangles = triangles.astype(np.int64).reshape(-1, 3) if triangles.size else np.zeros((0, 3), np.int64)
        if triangles.size and (triangles.min() < 0 or triangles.max() >= len(positions)):
            bad = int(np.argmax((triangles < 0).any(1) | (triangles >= len(positions)).any(1)))
            raise SceneError(f"<arrays>: face {bad} has a vertex index out of range "
                             f"{triangles[bad].tolist()} (there are {len(positions)} vertices)")
        if normals is None:
            normals = vertex_normals(positions, triangles)
        if uvs is None:
            uvs = np.zeros((len(positions), 2), np.float32)
        normals = np.asarray(normals, np.float32)
        uvs = np.asarray(uvs, np.float32)
        if normals.shape != positions.shape:
            raise SceneError(f"<arrays>: normals must have shape {positions.shape}, got {normals.shape}")
        if uvs.shape != (len(positions), 2):
            raise SceneError(f"<arrays>: uvs must have shape {(len(positions), 2)}, got {uvs.shape}")
        return cls(positions, normals, uvs, triangles.astype(np.int32),
                   np.zeros(len(triangles), np.int32), [material or Material()], camera=camera)

    # -- lights -------------------------------------------------------------------------------
    def add_point_light(self, position, color, radius) -> int:
        """A point light; returns its index in `lights`."""
        return self._add_light(structs.LIGHT_POINT, position, color, radius, (0.0, 0.0, -1.0), 0.0, 0.0)

    def add_spot_light(self, position, direction, color, radius, inner_deg, outer_deg,
                       shadow: bool = False, shadow_map_size: int = 1024) -> int:
        """A spot light lighting fully inside `inner_deg` of `direction`, fading to 0 at `outer_deg`.
        shadow=True gives it a perspective shadow map of `shadow_map_size`² texels over its cone."""
        inner_deg, outer_deg = float(inner_deg), float(outer_deg)
        if not 0.0 <= inner_deg <= outer_deg < 90.0:
            raise SceneError(f"spot light cone angles need 0 <= inner <= outer < 90 degrees, "
                             f"got inner={inner_deg} outer={outer_deg}")
        if not isinstance(shadow, (bool, np.bool_)):
            raise SceneError(f"spot light shadow must be True or False, got {shadow!r}")
        size = check_shadow_map_size(shadow_map_size) if shadow else 0
        return self._add_light(structs.LIGHT_SPOT, position, color, radius, direction,
                               np.cos(np.radians(inner_deg)), np.cos(np.radians(outer_deg)), size)

    def set_sun(self, direction, color, shadow: bool = True, shadow_map_size: int = 2048) -> "Sun":
        """A directional light travelling along `direction` that lights every pixel (no radius,
        no culling); shadow=True gives it orthographic cascaded shadow maps (RenderConfig
        sun_cascades) of `shadow_map_size`² texels each. Replaces any previous sun; `scene.sun =
        None` removes it."""
        self.sun = Sun(direction, color, shadow, shadow_map_size)
        return self.sun

    def set_environment(self, source, intensity: float = 1.0, rotation_deg: float = 0.0,
                        background: bool = True) -> Optional["Environment"]:
        """Light the scene with an HDR environment (image-based lighting, clrender.scene.environment):
        `source` is an .exr/.hdr/.pic path, an (H, 2H, 3) linear RGB array, "studio" (a neutral
        built-in one) or an Environment; `intensity` scales its radiance, `rotation_deg` turns it
        about +Y, `background` shows it where no surface is. None removes it. While an environment
        is set, the constant `ambient` term is not added (the environment is the ambient light).
        Replaces any previous environment (and load_scene's default one); returns the Environment."""
        from clrender.scene.environment import load_environment
        environment = None if source is None else load_environment(source, intensity, rotation_deg, background)
        if isinstance(self.settings, dict):
            self.settings.pop("default_environment", None)
        self.environment = environment
        return environment

    def add_random_lights(self, count: int, seed: int, radius=(0.5, 2.0), intensity: float = 1.0) -> np.ndarray:
        """`count` point lights uniform in the scene's bounds, reproducible for a seed; returns their indices."""
        count = int(count)
        if count < 0:
            raise SceneError(f"light count must be >= 0, got {count}")
        rmin, rmax = (float(radius), float(radius)) if np.isscalar(radius) else map(float, radius)
        if not 0.0 < rmin <= rmax or not np.isfinite(rmax):
            raise SceneError(f"light radius range must satisfy 0 < min <= max, got {radius!r}")
        rng = np.random.default_rng(seed)
        lo, hi = self.bounds().astype(np.float64)
        new = np.zeros(count, structs.light_dtype)
        new["position"] = rng.uniform(lo, hi, (count, 3))
        new["radius"] = rng.uniform(rmin, rmax, count)
        new["color"] = rng.uniform(0.2, 1.0, (count, 3)) * float(intensity)
        new["type"] = structs.LIGHT_POINT
        new["direction"] = (0.0, 0.0, -1.0)
        first = len(self.lights)
        self.lights = np.concatenate([self.lights, new])
        return np.arange(first, first + count)

    def add_light_particles(self, count: int, seed: int, radius=(0.5, 2.0), intensity: float = 1.0,
                            speed: float = 1.0, lifetime=(2.0, 5.0), bounds=None) -> np.ndarray:
        """`count` animated point lights (report V.1): they move, fade and respawn inside `bounds`
        (default: the scene's), updated on the device for `Renderer.render(..., time=t)`; the
        same seed and time give the same lights on every device. Returns their indices."""
        count = int(count)
        lo, hi = (self.bounds() if bounds is None else np.asarray(bounds, np.float64)).astype(np.float64)
        rmin, rmax = (float(radius), float(radius)) if np.isscalar(radius) else map(float, radius)
        lmin, lmax = map(float, lifetime)
        if count < 0 or not 0 < rmin <= rmax or not 0 < lmin <= lmax or speed < 0 or intensity < 0 \
                or lo.shape != (3,) or not np.all(lo <= hi):
            raise SceneError("light particles need count >= 0, 0 < radius min <= max, 0 < lifetime min <= max, "
                             "speed >= 0, intensity >= 0 and bounds (lo, hi) with lo <= hi")
        first = len(self.lights)
        placeholders = np.zeros(count, structs.light_dtype)
        placeholders["radius"] = rmin
        placeholders["position"] = (lo + hi) / 2
        self.lights = np.concatenate([self.lights, placeholders])
        self.particle_systems.append(ParticleSystem(first, count, int(seed) & 0xFFFFFFFF, tuple(lo), tuple(hi),
                                                    float(speed), lmin, lmax, rmin, rmax, float(intensity)))
        return np.arange(first, first + count)

    def _add_light(self, kind, position, color, radius, direction, cos_inner, cos_outer, shadow_size=0) -> int:
        position = np.asarray(position, np.float64).reshape(-1)
        color = np.asarray(color, np.float64).reshape(-1)
        direction = np.asarray(direction, np.float64).reshape(-1)
        radius = float(radius)
        if position.shape != (3,) or not np.isfinite(position).all():
            raise SceneError(f"light position must be 3 finite numbers, got {position.tolist()}")
        if color.shape != (3,) or not np.isfinite(color).all() or (color < 0).any():
            raise SceneError(f"light color must be 3 finite non-negative numbers, got {color.tolist()}")
        if not (np.isfinite(radius) and radius > 0):
            raise SceneError(f"light radius must be positive and finite, got {radius}")
        norm = np.linalg.norm(direction) if direction.shape == (3,) else 0.0
        if not (np.isfinite(norm) and norm > 0):
            raise SceneError(f"light direction must be a non-zero 3-vector, got {direction.tolist()}")
        rec = np.zeros(1, structs.light_dtype)
        rec[0] = (position, radius, color, kind, direction / norm, cos_outer, cos_inner, shadow_size, -1, 0.0)
        self.lights = np.concatenate([self.lights, rec])
        return len(self.lights) - 1

    # -- material variants (clrender.scene.variants) --------------------------------------------
    @property
    def variants(self) -> tuple:
        """The material variant names (glTF KHR_materials_variants), file order; () without any."""
        return () if self.material_variants is None else self.material_variants.names

    @property
    def variant(self) -> Optional[str]:
        """The active material variant's name; None: every mesh has its default material."""
        return None if self._variant is None else self.material_variants.names[self._variant]

    def set_variant(self, name: Optional[str]) -> None:
        """Activate material variant `name` (None: the default materials): the triangles of exactly the
        meshes the previous and the new variant map get their new materials, in a new
        `triangle_material` array (the next render uploads it). An unknown name is a one-line
        SceneError listing the variants."""
        mv = self.material_variants
        if name is None and mv is None:
            return
        if mv is None:
            raise SceneError(f"{self.source}: no material variant {name!r} (the scene has no material variants)")
        new = None if name is None else mv.index(name, self.source)
        mv.check(len(self.mesh_names), len(self.materials), self.source)
        self.triangle_material = mv.switch(self.triangle_mesh, self.triangle_material, self._variant, new)
        self._variant = new

    # -- queries ------------------------------------------------------------------------------
    @property
    def uv_set_count(self) -> int:
        """Texture coordinate sets: TEXCOORD_0 (`uvs`) and the `extra_uvs`."""
        return 1 + (0 if self.extra_uvs is None else len(self.extra_uvs))

    def uv_set(self, k: int) -> np.ndarray:
        return self.uvs if k == 0 else self.extra_uvs[k - 1]

    @property
    def triangle_object(self) -> np.ndarray:
        """(T,) int32: each triangle's index into `objects`."""
        return self.mesh_object[self.triangle_mesh]

    @property
    def triangle_count(self) -> int:
        return int(len(self.triangles))

    def triangle_source(self, index: int) -> tuple[str, int]:
        """Triangle index (as in Frame.triangle_id) -> (mesh name, face index in that mesh)."""
        if not 0 <= index < self.triangle_count:
            raise IndexError(f"triangle {index} out of range (scene has {self.triangle_count})")
        return self.mesh_names[int(self.triangle_mesh[index])], int(self.triangle_face[index])

    def bounds(self) -> np.ndarray:
        """(2, 3) min/max over finite vertices referenced by triangles."""
        pts = self.positions
        if self.triangle_count:      # a mask of the referenced vertices: np.unique's sort costs more
            used = np.zeros(len(pts), bool)
            used[self.triangles.reshape(-1)] = True
            pts = pts[used]
        pts = pts[np.isfinite(pts).all(1)]
        if len(pts) == 0:
            return np.zeros((2, 3), np.float32)
        return np.stack([pts.min(0), pts.max(0)])

    def default_camera(self) -> Camera:
        """The scene's own camera, else one framing the bounds from +Z."""
        if self.camera is not None:
            return self.camera
        lo, hi = self.bounds().astype(np.float64)
        center, radius = (lo + hi) / 2, max(float(np.linalg.norm(hi - lo)) / 2, 1e-3)
        eye = center + np.array([0.0, 0.35, 1.0]) / np.linalg.norm([0.0, 0.35, 1.0]) * radius * 2.2
        return Camera.look_at(eye, center, (0, 1, 0), 45.0, near=radius * 0.01, far=radius * 10)

    def validate(self) -> None:
        where = self.source
        nv, nt = len(self.positions), len(self.triangles)
        if self.normals.shape != (nv, 3) or self.uvs.shape != (nv, 2):
            raise SceneError(f"{where}: normals/uvs must have one entry per vertex ({nv})")
        if self.previous_positions is not None and np.shape(self.previous_positions) != (nv, 3):
            raise SceneError(f"{where}: previous_positions must have shape ({nv}, 3) like positions, "
                             f"got {np.shape(self.previous_positions)}")
        if nt and (self.triangles.min() < 0 or self.triangles.max() >= nv):
            raise SceneError(f"{where}: a triangle index is out of range (there are {nv} vertices)")
        if self.triangle_material.shape != (nt,):
            raise SceneError(f"{where}: triangle_material must have one entry per triangle ({nt})")
        check_positions(self.positions, where)
        if self.previous_positions is not None:
            check_positions(self.previous_positions, where, "previous_positions")
        if nt and (self.triangle_material.min() < 0 or self.triangle_material.max() >= len(self.materials)):
            raise SceneError(f"{where}: a triangle references a material that does not exist")
        if np.shape(self.triangle_mesh) != (nt,) or (nt and (self.triangle_mesh.min() < 0 or
                                                            self.triangle_mesh.max() >= len(self.mesh_names))):
            raise SceneError(f"{where}: triangle_mesh must index mesh_names ({len(self.mesh_names)}), one per triangle")
        extra = len(self.mesh_names) - len(self.mesh_object)
        if extra > 0 and self.mesh_object.ndim == 1:     # meshes appended after construction: one object each
            self.objects = list(self.objects) + [SceneObject(n, n, n) for n in self.mesh_names[-extra:]]
            self.mesh_object = np.concatenate([self.mesh_object, len(self.objects) - extra + np.arange(extra)]
                                              ).astype(np.int32)
        if self.mesh_object.shape != (len(self.mesh_names),) or (self.mesh_object.size and (
                self.mesh_object.min() < 0 or self.mesh_object.max() >= len(self.objects))):
            raise SceneError(f"{where}: mesh_object must map each of the {len(self.mesh_names)} meshes to one of the "
                             f"{len(self.objects)} objects")
        if not all(isinstance(o, SceneObject) for o in self.objects):
            raise SceneError(f"{where}: objects must be SceneObject records")
        if self.material_variants is not None:
            self.material_variants.check(len(self.mesh_names), len(self.materials), where)
        for i, entry in enumerate(self.cameras):
            if not (isinstance(entry, tuple) and len(entry) == 2 and isinstance(entry[0], str)
                    and isinstance(entry[1], Camera)):
                raise SceneError(f"{where}: cameras[{i}] must be a (name, Camera) pair, got {entry!r}")
        for name, shape in (("colors", (nv, 4)), ("tangents", (nv, 4))):
            a = getattr(self, name)
            if a is not None and (np.shape(a) != shape or not np.isfinite(a).all()):
                raise SceneError(f"{where}: {name} must be finite with shape {shape}, got {np.shape(a)}")
        k = self.uv_set_count - 1
        if self.extra_uvs is not None and np.shape(self.extra_uvs) != (k, nv, 2):
            raise SceneError(f"{where}: extra_uvs must have shape (K, {nv}, 2), got {np.shape(self.extra_uvs)}")
        for m in self.materials:
            for slot, (tex, uv) in {**m.textures_used(), **m.layer_textures_used(), **m.tx_textures_used()}.items():
                if not tex < len(self.textures):
                    raise SceneError(f"{where}: material {m.name!r} references missing texture {tex} ({slot})")
                if uv.texcoord >= self.uv_set_count:
                    raise SceneError(f"{where}: material {m.name!r} reads {slot} from TEXCOORD_{uv.texcoord}, but the "
                                     f"scene has {self.uv_set_count} texture coordinate set(s)")

    def summary(self) -> dict:
        lo, hi = self.bounds()
        return {
            "source": self.source,
            "triangles": self.triangle_count,
            "vertices": int(len(self.positions)),
            "meshes": len(self.mesh_names),
            "objects": len(self.objects),
            "materials": len(self.materials),
            "textures": len(self.textures),
            "texture_sizes": [list(t.rgba.shape[1::-1]) for t in self.textures],
            "alpha_masked_materials": sum(m.alpha_mode == "MASK" for m in self.materials),
            "transparent_materials": sum(m.see_through for m in self.materials),   # BLEND or transmissive
            "single_sided_materials": sum(not m.double_sided for m in self.materials),
            "bounds_min": lo.tolist(),
            "bounds_max": hi.tolist(),
            "camera": None if self.camera is None else _camera_summary(self.camera),
            "cameras": [{"name": name, **_camera_summary(cam)} for name, cam in self.cameras],
        }


def _camera_summary(cam: Camera) -> dict:
    return {"eye": cam.eye, "target": cam.target,
            **({"projection": "orthographic", "xmag": cam.xmag, "ymag": cam.ymag}
               if cam.is_orthographic else {"fov_y_deg": cam.fov_y_deg})}

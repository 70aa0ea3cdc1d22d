"""Light particles (report V.1): device-updated lights, a pure function of (seed, index, time).

Checked against a NumPy re-implementation of the same hash and motion, and for exact
agreement between runs and devices."""
import numpy as np
import pytest

import clrender
from clrender import Scene


def lowbias32(x):
    x = np.asarray(x, np.uint32).copy()
    x ^= x >> np.uint32(16); x *= np.uint32(0x7feb352d); x ^= x >> np.uint32(15)
    x *= np.uint32(0x846ca68b); x ^= x >> np.uint32(16)
    return x


def rand01(seed, particle, generation, channel):
    with np.errstate(over="ignore"):
        inner = lowbias32(np.asarray(generation, np.uint32) * np.uint32(0x85ebca6b) + np.uint32(channel))
        h = lowbias32(np.uint32(seed) ^ lowbias32((np.asarray(particle, np.uint32) * np.uint32(0x9e3779b9)) ^ inner))
    return (h >> np.uint32(8)).astype(np.float64) / 16777216.0


def reference_lights(ps, t):
    p = np.arange(ps.count, dtype=np.uint32)
    const = np.uint32(0xFFFFFFFF)
    life = ps.life_min + rand01(ps.seed, p, const, 0) * (ps.life_max - ps.life_min)
    phase = rand01(ps.seed, p, const, 1) * life
    cycles = np.floor((t + phase) / life)
    age = t + phase - cycles * life
    g = cycles.astype(np.int64).astype(np.uint32)
    lo, hi = np.asarray(ps.lo), np.asarray(ps.hi)
    start = np.stack([lo[k] + rand01(ps.seed, p, g, 2 + k) * (hi[k] - lo[k]) for k in range(3)], 1)
    direction = np.stack([rand01(ps.seed, p, g, 5 + k) * 2 - 1 for k in range(3)], 1)
    a = age / life
    fade = 4 * a * (1 - a)
    color = np.stack([ps.intensity * fade * (0.2 + 0.8 * rand01(ps.seed, p, const, 8 + k)) for k in range(3)], 1)
    radius = ps.radius_min + rand01(ps.seed, p, const, 2) * (ps.radius_max - ps.radius_min)
    return start + direction * (ps.speed * age)[:, None], radius, color


@pytest.fixture
def particle_scene():
    s = Scene.from_arrays(np.array([[-5, 0, -5], [5, 0, -5], [0, 0, 5]], np.float32), [[0, 1, 2]])
    s.add_point_light((0, 1, 0), (1, 1, 1), 2.0)        # a static light before the system
    s.add_light_particles(500, seed=11, radius=(0.2, 0.6), intensity=3.0, speed=1.5, lifetime=(1.0, 4.0),
                          bounds=((-5, 0, -5), (5, 3, 5)))
    return s


@pytest.mark.parametrize("t", [0.0, 0.75, 13.3])
def test_particles_match_numpy_reference(make_renderer, particle_scene, t):
    lights = make_renderer(16, 16).lights_at(particle_scene, t)
    ps = particle_scene.particle_systems[0]
    pos, radius, color = reference_lights(ps, t)
    got = lights[ps.first:ps.first + ps.count]
    np.testing.assert_allclose(got["position"], pos, rtol=1e-5, atol=1e-4)
    np.testing.assert_allclose(got["radius"], radius, rtol=1e-6)
    # The kernel's age = (t + phase) - cycles·life is float32: ~ulp(t) absolute error in the fade.
    np.testing.assert_allclose(got["color"], color, rtol=1e-5, atol=2e-5 * ps.intensity)
    np.testing.assert_array_equal(lights[0], particle_scene.lights[0])    # static lights untouched


def test_particles_are_deterministic_and_move(make_renderer, particle_scene):
    r = make_renderer(16, 16)
    a, b = r.lights_at(particle_scene, 2.5), r.lights_at(particle_scene, 2.5)
    assert a.tobytes() == b.tobytes()
    c = r.lights_at(particle_scene, 2.6)
    moved = np.linalg.norm(c["position"][1:] - a["position"][1:], axis=1)
    assert np.median(moved) > 0.05


def test_particles_identical_on_every_device(particle_scene):
    from clrender.device.probe import select_devices
    results = {d.label: clrender.Renderer(8, 8, device=d.id).lights_at(particle_scene, 7.125).tobytes()
               for d in select_devices("all")}
    assert len(set(results.values())) == 1, list(results)


def test_particles_light_the_frame_at_their_time(make_renderer, particle_scene):
    cam = clrender.Camera.look_at((0, 8, 8), (0, 0, 0))
    r = make_renderer(64, 48)
    f0, f1 = r.render(particle_scene, cam, time=0.0), r.render(particle_scene, cam, time=1.0)
    assert f0.stats["time"] == 0.0 and f1.stats["time"] == 1.0
    assert not np.array_equal(f0.color, f1.color)
    again = r.render(particle_scene, cam, time=1.0)
    assert np.array_equal(again.color, f1.color)

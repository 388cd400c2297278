"""One random object of the coverage study: its shape, material, friction, fingertip, squeeze and weight.

The drawing follows :mod:`verification.random_scenes` with ranges of its own (objects a hand-sized gripper
meets, soft enough for the fingers' patches to matter, light and heavy enough that some are held and some
not), and adds a third shape, the capsule (:func:`capsule`).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

#: The shapes drawn, with equal chances.
SHAPES = ("ellipsoid", "fused spheres", "capsule")
#: Parameter ranges of a random object (SI units; angles in degrees).
RANGES: dict[str, tuple[float, float]] = {
    "size": (0.02, 0.045),  # the first semi-axis, the larger sphere's radius, or the capsule's radius, metres
    "aspect_y": (0.6, 1.2),  # ellipsoid: b / a
    "aspect_z": (0.6, 1.2),  # ellipsoid: c / a
    "sphere_ratio": (0.6, 1.0),  # fused spheres: r₂ / r₁ (r₁ is the larger)
    "overlap": (0.45, 0.9),  # fused spheres: distance / (r₁ + r₂)
    "length_ratio": (0.5, 2.0),  # capsule: length of the cylinder / its radius
    "log10_young": (math.log10(5e3), math.log10(1e5)),  # E log-uniform from 5 to 100 kPa
    "poisson": (0.2, 0.45),
    "mu_finger": (0.3, 1.0),
    "mu_table": (0.3, 1.0),
    "radius_ratio": (0.3, 0.6),  # fingertip radius / the object's smallest radius
    "tilt": (0.0, 30.0),  # the squeeze directions' angle below the horizontal
    "ratio": (0.0, 1.0),  # s, the second finger's share of the squeeze
    "density": (300.0, 1500.0),  # kg/m³
}
#: Vertices aimed at on the object's first (level 0) mesh.
TARGET_VERTICES = 500


def capsule(radius: float, length: float, mesh_size: float) -> tuple[np.ndarray, np.ndarray]:
    """Tetrahedral mesh of a capsule: a cylinder of ``radius`` and ``length`` along x, centred on the origin,
    closed by two hemispherical caps (gmsh's OpenCASCADE kernel, in the quiet deterministic session of
    :func:`fem_grasp.mesh.gmsh_session.gmsh_model`).

    Parameters
    ----------
    radius, length : metres (``length`` is the cylinder's, without the caps; its total length is
        ``length + 2 radius``)
    mesh_size : target edge length, metres

    Returns
    -------
    points : (n, 3) float64 ndarray
    tets : (t, 4) int64 ndarray, positively oriented
    """
    from fem_grasp.mesh.gmsh_session import check_lengths, extract_tets, generate, gmsh_model, surface_algorithm

    r, c = float(radius), float(length)
    check_lengths(radius=r, length=c, mesh_size=mesh_size)
    alg = surface_algorithm("auto", capsule_volume(r, c), mesh_size)
    with gmsh_model("capsule", mesh_size, alg) as gmsh:
        occ = gmsh.model.occ
        body = occ.addCylinder(-0.5 * c, 0.0, 0.0, c, 0.0, 0.0, r)
        caps = [occ.addSphere(-0.5 * c, 0.0, 0.0, r), occ.addSphere(0.5 * c, 0.0, 0.0, r)]
        occ.fuse([(3, body)], [(3, t) for t in caps])
        occ.synchronize()
        generate(gmsh, mesh_size)
        points, tets = extract_tets(gmsh)
    return points, tets


def capsule_volume(radius: float, length: float) -> float:
    """π r² L + 4/3 π r³: the cylinder and its two hemispherical caps."""
    return math.pi * radius**2 * length + 4.0 / 3.0 * math.pi * radius**3


@dataclass(frozen=True)
class CoverageObject:
    """The parameters of one random object (see :data:`RANGES`); the parameters its shape does not use are
    drawn too, so that each draw takes the same numbers from the generator."""

    shape: str
    size: float
    aspect_y: float
    aspect_z: float
    sphere_ratio: float
    overlap: float
    length_ratio: float
    log10_young: float
    poisson: float
    mu_finger: float
    mu_table: float
    radius_ratio: float
    tilt: float
    ratio: float
    density: float

    @classmethod
    def draw(cls, rng: np.random.Generator) -> "CoverageObject":
        """An object with its shape uniform among :data:`SHAPES` and every parameter uniform in its range."""
        values = {k: float(rng.uniform(lo, hi)) for k, (lo, hi) in RANGES.items()}
        return cls(shape=str(rng.choice(SHAPES)), **values)

    @classmethod
    def of_seed(cls, seed: int) -> "CoverageObject":
        """Object ``i`` of a study started at ``seed0``: ``of_seed(seed0 + i)``."""
        return cls.draw(np.random.default_rng(seed))

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    @property
    def young(self) -> float:
        return 10.0**self.log10_young

    def solid(self) -> tuple[Any, float, float]:
        """(a builder: mesh size -> (points, tets), the exact volume, the smallest radius)."""
        from fem_grasp.mesh.shapes import ellipsoid, fused_spheres

        if self.shape == "ellipsoid":
            axes = (self.size, self.size * self.aspect_y, self.size * self.aspect_z)
            return (lambda h: ellipsoid(axes, h)), 4.0 / 3.0 * math.pi * float(np.prod(axes)), min(axes)
        if self.shape == "fused spheres":
            r1, r2 = self.size, self.size * self.sphere_ratio
            d = max(self.overlap * (r1 + r2), 1.05 * (r1 - r2))
            lens = math.pi * (r1 + r2 - d) ** 2 * (d * d + 2 * d * (r1 + r2) - 3 * (r1 - r2) ** 2) / (12 * d)
            return (lambda h: fused_spheres((r1, r2), d, h)), 4.0 / 3.0 * math.pi * (r1**3 + r2**3) - lens, r2
        if self.shape == "capsule":
            r, c = self.size, self.size * self.length_ratio
            return (lambda h: capsule(r, c, h)), capsule_volume(r, c), r
        raise ValueError(f"unknown shape {self.shape!r}; choose from {SHAPES}")

    def mesh(self) -> tuple[Any, float]:
        """The level-0 mesh, at about :data:`TARGET_VERTICES` vertices; and the object's smallest radius."""
        from fem_grasp import TetMesh
        from fem_grasp.mesh.gmsh_session import mesh_with_vertex_count

        build, volume, smallest = self.solid()
        h = (1.5 * volume / TARGET_VERTICES) ** (1.0 / 3.0)  # gmsh gives about 1.5 V / h³ vertices here
        try:
            points, tets = mesh_with_vertex_count(build, TARGET_VERTICES, 0.1, initial_size=h, max_calls=8)
        except RuntimeError:  # a count the mesher skips over: the size the rule gives
            points, tets = build(h)
        return TetMesh(points, tets), smallest

    def body(self, mesh: Any) -> Any:
        from fem_grasp import Body

        return Body(mesh, self.young, self.poisson, density=self.density)

    def pickup_arguments(self, smallest: float) -> dict[str, Any]:
        """Friction, fingertip radius, squeeze directions (tilted below the horizontal) and ratio, as
        :meth:`verification.random_scenes.RandomScene.pickup_arguments` makes them."""
        t = math.radians(self.tilt)
        d1 = np.array([0.0, math.cos(t), -math.sin(t)])
        d2 = np.array([0.0, -math.cos(t), -math.sin(t)])
        return {"mu_finger": self.mu_finger, "mu_table": self.mu_table,
                "finger_radius": self.radius_ratio * smallest, "directions": (d1, d2), "ratio": self.ratio}

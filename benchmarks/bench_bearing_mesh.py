"""Time the bearing hinge's geometry and volume meshes, part by part.

Usage: .venv/bin/python benchmarks/bench_bearing_mesh.py [--scale S] [--preload N]

Each part goes through ``mesh.build.mesh_part`` (prismatic parts are swept, the rings
and balls volume-meshed by ``mesh.volume.mesh_solid_hex``) with the part's own global
size from ``BenchSettings``; then every named face of the part must select facets.
Peak memory is the process's maximum resident set size after each part (gmsh runs in
this process), so it only ever grows.

Measured on the 2-core machine (default 708C pair, sizes as in BenchSettings):
geometry 0.8 s + meshes 76 s = 77 s, 332 022 hexahedra, 414 980 nodes (balls ≈ 9 000
hexes and ≈ 1.1 s each, inner rings 32 000 / 5.5 s, outer rings 41 000 / 11 s), min
scaled Jacobian 0.087 (plate, swept) / 0.098 (outer ring), every named face non-empty.
With --scale 1.5: 166 644 hexahedra.
"""

from __future__ import annotations

import argparse
import math
import resource
import time
from dataclasses import dataclass

from cad.bearing import make_bearing_hinge
from cad.bearing_geometry import BearingHingeParams
from mesh.build import SET_TOL_MM, mesh_part
from mesh.facets import boundary_facets, select_facets
from mesh.quality import check_quality, hex_volumes
from mesh.settings import MeshSettings

WIDTHS = (9, 9, 8, 10, 8, 9)


@dataclass(frozen=True)
class BenchSettings:
    """Hexahedron sizes [mm] of the bearing hinge at refinement 0."""

    ball_mm: float = 0.6
    ring_mm: float = 0.8
    pin_mm: float = 1.2
    plate_mm: float = 1.2
    lug_mm: float = 2.5
    master_mm: float = 0.15
    slave_mm: float = 0.1

    def global_mm(self, part: str) -> float:
        if part.startswith("ball"):
            return self.ball_mm
        if "ring" in part:
            return self.ring_mm
        return {"pin": self.pin_mm, "preload_plate": self.plate_mm}.get(part, self.lug_mm)

    def for_part(self, part: str) -> MeshSettings:
        return MeshSettings(
            size_mm=self.global_mm(part),
            contact_size_mm=self.master_mm,
            slave_ratio=self.master_mm / self.slave_mm,
        )

    def scaled(self, s: float) -> BenchSettings:
        return BenchSettings(*(s * v for v in vars(self).values()))


def hertz_semi_axes_mm(
    p: BearingHingeParams, preload_n: float
) -> dict[str, tuple[float, float, float]]:
    """Return (ball load Q [N], semi-major a, semi-minor b [mm]) of the inner and outer contacts.

    Q = F_p / (Z sin α); Hamrock–Brewe fits for the ellipticity and elliptic integral;
    E' = E/(1 − ν²) for two GCr15 bodies.
    """
    alpha = math.radians(p.contact_angle_deg)
    q = preload_n / (p.ball_count * math.sin(alpha))
    dw = p.ball_diameter_mm
    gamma = dw * math.cos(alpha) / p.pitch_diameter_mm
    e_star = p.bearing_material.young_mpa / (1.0 - p.bearing_material.poisson**2)
    out = {}
    for race, f, rx in (
        ("inner", p.inner_curvature_ratio, 0.5 * dw * (1.0 - gamma)),
        ("outer", p.outer_curvature_ratio, 0.5 * dw * (1.0 + gamma)),
    ):
        ry = f * dw / (2.0 * f - 1.0)
        r = 1.0 / (1.0 / rx + 1.0 / ry)
        k = 1.0339 * (ry / rx) ** 0.636
        ell = 1.0003 + 0.5968 * rx / ry
        a = (6.0 * k * k * ell * q * r / (math.pi * e_star)) ** (1.0 / 3.0)
        b = (6.0 * ell * q * r / (math.pi * k * e_star)) ** (1.0 / 3.0)
        out[race] = (q, a, b)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scale", type=float, default=1.0, help="multiply every size")
    parser.add_argument(
        "--preload", type=float, default=200.0, help="F_p for the Hertz estimate [N]"
    )
    parser.add_argument("--only", default="", help="mesh only parts whose name starts with this")
    args = parser.parse_args()
    settings = BenchSettings().scaled(args.scale)
    print(settings)

    t0 = time.perf_counter()
    p = BearingHingeParams()
    model = make_bearing_hinge(p)
    t_cad = time.perf_counter() - t0
    for race, (q, a, b) in hertz_semi_axes_mm(p, args.preload).items():
        print(
            f"Hertz {race} at F_p={args.preload:g} N: Q={q:.1f} N, a={a:.3f} mm, b={b:.3f} mm, "
            f"sqrt(ab)={math.sqrt(a * b):.3f} mm"
        )
    print(f"geometry: {len(model.parts)} parts in {t_cad:.2f} s\n")
    head = ("part", "n_hex", "n_nodes", "min SJ", "vol err", "time s", "peak MB")
    print(f"{head[0]:<16}" + "".join(f"{h:>{w}}" for h, w in zip(head[1:], WIDTHS, strict=True)))
    total_hex = total_nodes = 0
    empty: list[str] = []
    t_mesh = time.perf_counter()
    for part in model.parts:
        if not part.name.startswith(args.only):
            continue
        t = time.perf_counter()
        nodes, hexes = mesh_part(model, part, settings.for_part(part.name))
        dt = time.perf_counter() - t
        sj = check_quality(nodes, hexes)
        err = hex_volumes(nodes, hexes).sum() / part.solid.volume - 1.0
        facets, _ = boundary_facets(hexes)
        for face in model.faces.values():
            if face.part == part.name:
                n = int(select_facets(nodes, facets, face.surface, face.box, SET_TOL_MM).sum())
                empty += [face.name] if n == 0 else []
        peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
        total_hex += len(hexes)
        total_nodes += len(nodes)
        print(
            f"{part.name:<16}{len(hexes):>9}{len(nodes):>9}{sj:>8.3f}{err:>10.2e}{dt:>8.2f}{peak:>9.0f}"
        )
    t_mesh = time.perf_counter() - t_mesh
    print(f"{'total':<16}{total_hex:>9}{total_nodes:>9}{'':>8}{'':>10}{t_mesh:>8.2f}")
    print(f"geometry + mesh: {t_cad + t_mesh:.1f} s; named faces with no facets: {empty or 'none'}")


if __name__ == "__main__":
    main()

"""Linear-elastic finite elements: quadrature → element → assembly → solve.

A two-element bar, 2 × 1 × 1 mm, pulled with 100 N along x; the support at x = 0 fixes
u_x and just enough other DOFs to stop rigid motion, so the bar contracts freely and the
end moves by F L / (E A) = 100 · 2 / (200 000 · 1) = 0.001 mm:

>>> import numpy as np
>>> from cad.materials import Material
>>> from fe.assembly import assemble_stiffness, dofs_of, solve_dirichlet
>>> from mesh.hexmesh import HexMesh
>>> CORNERS = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0),
...            (0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)]  # VTK order
>>> def bar_mesh():
...     ijk = [(i, j, k) for k in (0, 1) for j in (0, 1) for i in (0, 1, 2)]
...     node = {p: n for n, p in enumerate(ijk)}
...     hexes = [[node[(i + a, b, c)] for a, b, c in CORNERS] for i in (0, 1)]
...     steel = Material("steel", 200_000.0, 0.3)
...     return HexMesh(np.array(ijk, dtype=np.float64), np.array(hexes),
...                    np.zeros(2, dtype=np.int64), ("bar",), (steel,), {})
>>> mesh = bar_mesh()
>>> K = assemble_stiffness(mesh)  # ElementType.INCOMPATIBLE by default
>>> x = mesh.nodes
>>> root, end = np.flatnonzero(x[:, 0] == 0.0), np.flatnonzero(x[:, 0] == 2.0)
>>> at = {tuple(p): n for n, p in enumerate(x)}
>>> fixed = np.concatenate([dofs_of(root, [0]), dofs_of([at[0, 0, 0]], [1, 2]),
...                         dofs_of([at[0, 1, 0]], [2]), dofs_of([at[0, 0, 1]], [1])])
>>> f = np.zeros(K.shape[0])
>>> f[dofs_of(end, [0])] = 100.0 / len(end)
>>> u = solve_dirichlet(K, f, fixed).reshape(-1, 3)
>>> print(np.round(u[end, 0], 9))
[0.001 0.001 0.001 0.001]
"""

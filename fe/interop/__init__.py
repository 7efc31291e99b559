"""Hand a hinge model to the tools our users already have (ABAQUS, CalculiX) and read back.

* :mod:`fe.interop.inp` — write a meshed hinge as an ABAQUS/CalculiX input deck: nodes,
  C3D8I elements per part, materials, named node/element/surface sets, frictional contact
  pairs (slave = pin side), ties, the grip boundary conditions and the load history
  0 → +Fg → −Fg → +Fg as three ``*STEP`` blocks (:mod:`fe.interop.inp_steps`), all
  commented, with labels and numbers as :mod:`fe.interop.inp_names` writes them;
* :mod:`fe.interop.deck_settings` — what the deck is asked to be (``DeckSettings``: load,
  penalty or mortar contact, stick slope, increments, ccx tolerances);
* :mod:`fe.interop.ccx` — run CalculiX (``ccx``) on a deck and read its ``.dat`` file
  (the grip displacement and the force through the hinge per increment) and ``.sta`` file
  (increments, iterations, cut-backs).

They import only ``cad``, ``mesh``, numpy and the standard library, so they do not move
when the solver inside ``fe`` does. A one-element cube pulled by 100 N:

>>> import numpy as np
>>> from cad.materials import Material
>>> from cad.model import FaceRole, NamedFace
>>> from cad.surfaces import Plane
>>> from fe.interop.deck_settings import DeckSettings
>>> from fe.interop.inp import deck_text
>>> from mesh.hexmesh import HexMesh
>>> corners = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0),
...            (0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)]  # VTK order = C3D8 order
>>> cube = HexMesh(np.array(corners, dtype=np.float64), np.arange(8)[None, :],
...                np.zeros(1, dtype=np.int64), ("block",), (Material("steel", 2e5, 0.3),),
...                {"xmin": [[0, 4, 7, 3]], "xmax": [[1, 2, 6, 5]]})
>>> faces = {"xmin": NamedFace("xmin", "block", FaceRole.FIXED, Plane((0, 0, 0), (-1, 0, 0))),
...          "xmax": NamedFace("xmax", "block", FaceRole.LOAD, Plane((1, 0, 0), (1, 0, 0)))}
>>> text = deck_text(cube, faces, DeckSettings(amplitude_n=100.0))
>>> print(text.count("*STEP"), "*ELEMENT, TYPE=C3D8I, ELSET=block" in text)
3 True
"""

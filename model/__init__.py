"""The model: what a MODEL.toml holds, and the service that runs it at design points.

* :mod:`model.spec` — ``ModelSpec`` (hinge kind and parameters, mesh, load protocol,
  effects), ``DesignPoint`` and the content hashes that key geometries and results;
* :mod:`model.file` — MODEL.toml read and written;
* :mod:`model.store` — computed cycles kept by result key, written atomically;
* :mod:`model.service` — ``ModelService``: each geometry prepared once, every point run
  on it (or read back from the store), failures recorded, duplicates run once.

Every command that runs a model (``cycle``, ``sweep``, ``study``, ``compare``, ``synth``,
``diagnose``, ``calibrate``) goes through here; ``validation`` and ``studies`` sit on top.
"""

"""`osmap surface`: fold-free quad grids on point-sampled surfaces with OS-Map.

Modules, one job each:
- shapes.py   built-in analytic surfaces (roll, torus, sphere, cylinder) and their parameters
- pointio.py  reading point clouds / meshes, area sampling, input checks
- frames.py   cartesian / cylindrical / spherical frames of the data space
- fit.py      --grid / --vary parsing, building and training the OSMap (or the classic SOM)
- metrics.py  shortcut edges, flipped quads, corner angles, fit error, windings
- geodesic.py surface distances on sampled surfaces without a parameterisation
- export.py   OBJ / PLY text and the output path checks
- preview.py  numpy wireframe rasteriser for the preview PNG
- job.py      the options as one record (SurfaceRequest) and the run (SurfaceJob)
  (the click command is osmap_cli.commands.surface)
Nothing numba-heavy is imported here.
"""

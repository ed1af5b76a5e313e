"""The structure-first solid method's engine (`osmap solid --method structure`, the default):
read what structure the exemplar shows, build that structure in 3D, fill in the appearance.

One job a module:
- segment: the exemplar's phases (colour clusters in CIELAB), read alike on exemplars and
  on a volume's slices;
- measures: orientation (structure tensor), autocorrelation, layer period, lattice test,
  grey-level morphology, distance transforms;
- profiles: the particle profiles' statistics (area fraction, size distribution, solidity,
  elongation);
- analysis: what the exemplar shows: particles, layers, veins, a phase field or none
  (`analyse`);
- particles, cells, layers, sheets, field: the 3D structures and the fitting of their models
  (stereology by simulation, a Laguerre tessellation with antialiased walls, band sequences,
  bands of a warped turbulent field, a truncated Gaussian field); noise: smooth random fields;
- method: the analysis over the exemplars and the model fitted (`plan`), the volume's
  structure (`build_structure`), the final colour matching (`finish`);
- fill: the guided slice-window optimisation that gives the structure its appearance;
  detail: the residual detail (copied, or noise drawn out along the sheets); layer_scale: the
  band widths a layered volume holds and the scale its faces show; sheared: the exemplar
  sheared along the bands of a face that shows layers at another angle; particle_colour,
  crowding: each particle's colours after the fill;
- slices, meter, picture: cuts through volumes, the profile meter, the --analyse picture.

This package imports nothing heavy at import time; STRUCTURES is the --structure choice list.
"""

STRUCTURES = ("auto", "particles", "layers", "veins", "field", "none")

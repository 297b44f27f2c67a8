"""Layer 5, evaluation and teaching: the quality figures, the baselines compared with, generated test scenes.

- :mod:`.quality` straightness, distortion, fold-over, tear, coverage, displacement,
  fidelity of points and cages, kinks: all measured on a warp's inverse map.
- :mod:`.baselines` the authors' implementation choices and other blends, for comparison.
- :mod:`.scenes` synthetic rooms with known straight edges, and families of scenes.
"""

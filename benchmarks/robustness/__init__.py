"""Geometry robustness study of qdrefine (issue 7, part 1).

Modules, one concern each:

* :mod:`.exact`      exact signs and areas on float64 input (Python integers, float filter)
* :mod:`.families`   seeded families of hard triangles and their placements
* :mod:`.naive`      7T-QD decided in plain float64, as a user would write it from the paper
* :mod:`.checks`     validity of partitions and triangulations of the nine points
* :mod:`.delaunay`   SciPy/Qhull, Triangle and qdrefine's 7T-D on the nine points
* :mod:`.refinement` patches refined 1 to 4 levels, checked exactly
* :mod:`.exhibit`    a nine-point set on which a floating-point Delaunay fails, drawn
* :mod:`.report`     the markdown page and the JSON results
* ``study.py``       the command that runs everything

Run ``python benchmarks/robustness/study.py --help``.
"""

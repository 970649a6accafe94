"""Twin vs measurement: find where they disagree, name the missing effect, add it, show the gap shrink.

Pure NumPy (no middleware): ``synth`` writes datasets with hidden effects, ``workflow`` runs the
detect -> name -> add -> re-simulate loop, ``effects`` is the library of named effects.
"""

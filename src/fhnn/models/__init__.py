"""Models: FHNN and the baselines behind one vector-field interface ``ṡ = f(s, t, F_ext)``."""

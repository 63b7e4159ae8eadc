"""The LBL range model: what a beacon's ranges are predicted to be, and how likely they are.

:mod:`.paths` (the direct path and the surface bounce, triangle or double),
:mod:`.geometry` (straight-ray distances and the per-range plane inversion),
:mod:`.refracted` (the same through a sound-speed profile), :mod:`.beacon_geometry`
(one beacon's precomputed geometry), :mod:`.likelihood` (the mixture log-likelihood and
E-step) and :mod:`.loglik_kernel` (its vectorised kernel over many parameter sets).
"""

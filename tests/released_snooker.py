"""emcee 3.1.6's snooker move as released, for the tests that must catch it.

Written here from the description of the upstream fix (emcee pull request #531),
so that the checks are shown to catch it whatever emcee version is installed:
``tests/test_mcmc.py`` (standard normals) and ``tests/lbl/bayes/test_sbc.py``
(simulation-based calibration of a beacon's posterior).
"""

import emcee
import numpy as np


class ReleasedSnooker(emcee.moves.DESnookerMove):
    """emcee 3.1.6's snooker, as released: direction over sqrt(distance), half the factor."""

    def get_proposal(self, s, c, random):
        ns, ndim = s.shape
        q, factor = np.empty_like(s), np.empty(ns)
        for i in range(ns):
            w = np.array([c[j][random.randint(len(c[j]))] for j in range(3)])
            random.shuffle(w)
            z, z1, z2 = w
            norm = np.linalg.norm(s[i] - z)
            u = (s[i] - z) / np.sqrt(norm)
            q[i] = s[i] + u * self.gammas * (np.dot(u, z1) - np.dot(u, z2))
            factor[i] = 0.5 * (ndim - 1.0) * (np.log(np.linalg.norm(q[i] - z)) - np.log(norm))
        return q, factor

"""The posterior of one beacon: sampling, PSIS-LOO of the priors, calibration (docs/bayes.md)."""

"""Bayesian inference for the rig: priors, likelihood, sampling, propagation, comparison."""

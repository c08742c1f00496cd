"""Probabilistic studies of key groups: sampling the uncertain inputs, running the samples, and
estimating small probabilities of failure (`kgm.studies.reliability`)."""

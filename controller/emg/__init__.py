"""Muscle activity from surface EMG: the montage (which channel is which muscle), the
standard amplitude processing chain (DC removal, zero-phase band-pass, optional notch,
full-wave rectification, low-pass envelope) and its causal twin for the live strip,
normalisation (MVC, task peak, task mean), quality flags per channel, and the outcomes
per lift (peak, mean, integrated EMG, the envelope over the normalised lift cycle).

Pure numpy/scipy: arrays are (n_samples, n_channels) in volts, `fs` in Hz."""

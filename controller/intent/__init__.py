"""Intent estimation (the paper's "Learning motion models" and "Estimating intent"):
the PPCA motion models, onset detection by subsequence DTW, the posterior category
probabilities, the Kalman hip velocities, the E-UMC's calibration, and the
segmentation of demonstrations into lifts the models are fitted to."""

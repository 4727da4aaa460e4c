"""Training data from the simulator and the training of the residual regressor and the GRU."""

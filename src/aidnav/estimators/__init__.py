"""Non-Kalman estimators of the seeds (polarization attitude, DGPS relative LSQ, satcom servo angles)."""

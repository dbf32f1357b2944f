"""Camera, table and projector geometry, assembly-error measurement, simulator parameter fitting."""

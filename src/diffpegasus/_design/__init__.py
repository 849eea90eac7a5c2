"""Input design: excitations chosen through the differentiable output-error model."""

"""fricbench: servo-friction compensation benchmark."""

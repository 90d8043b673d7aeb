"""Training of the embedded default encoders (seeded, CPU): ``tabletop train vision|audio``."""

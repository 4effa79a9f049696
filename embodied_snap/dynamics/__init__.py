"""Dynamics model of paper section IV-A: GRU ensemble (Eq. 3-4), hold model, gates."""

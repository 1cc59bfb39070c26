"""Gait: learn models, predict/retime/restyle, live preview."""

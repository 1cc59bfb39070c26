"""Track Keyframes and its setup: footage, camera, body envelopes, keys and confidence curves."""

"""Shared by every feature: F-curve access (slotted actions), armature <-> core poses, reports."""

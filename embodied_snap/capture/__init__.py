"""Readers of motion-capture exports (Motive CSV, C3D) into plain tables, and a rigid-body fit."""

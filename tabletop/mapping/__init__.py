"""Mapping: encoders, voxel fusion, the localisation modules, heatmaps and the AVLMap."""

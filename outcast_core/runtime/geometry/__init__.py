"""Cameras, colour, ray marching and Direct shadows, the full-resolution transfer."""

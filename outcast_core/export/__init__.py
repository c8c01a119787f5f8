"""ONNX export of the trained networks into ``models/`` with a checked manifest."""

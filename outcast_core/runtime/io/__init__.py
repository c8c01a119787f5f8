"""Reading and writing: images and their EXIF, phone depth, camera pose, ONNX models."""

"""Thin onnxruntime wrappers used by the evaluation (timed, numpy in / out)."""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np


class TimedModel:
    """An ONNX model with its manifest; :meth:`run` returns outputs and seconds taken.

    Args:
        path: the ``.onnx`` file (its manifest is the ``.json`` beside it, if any).
        threads: onnxruntime intra-op threads.
    """

    def __init__(self, path: str | Path, threads: int = 2) -> None:
        import onnxruntime as ort

        self.path = Path(path)
        if not self.path.is_file():
            raise FileNotFoundError(f"expected a model file at {self.path}, got none")
        opts = ort.SessionOptions()
        opts.intra_op_num_threads = threads
        opts.inter_op_num_threads = 1
        self.session = ort.InferenceSession(
            str(self.path), opts, providers=["CPUExecutionProvider"]
        )
        man = self.path.with_suffix(".json")
        self.manifest = json.loads(man.read_text()) if man.is_file() else {}
        self.inputs = [i.name for i in self.session.get_inputs()]

    def run(self, **inputs: np.ndarray) -> tuple[list[np.ndarray], float]:
        feed = {k: np.ascontiguousarray(inputs[k], dtype=np.float32) for k in self.inputs}
        t = time.perf_counter()
        out = self.session.run(None, feed)
        return out, time.perf_counter() - t

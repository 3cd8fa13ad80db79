"""The exported policy run by onnxruntime: raw observation entries in, the action in [-1, 1] out."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np

from ..exceptions import InvalidConfig


class OnnxPolicy:
    """policy.onnx on one CPU thread (the controller's cycle is one small MLP: threads only add latency).

    Args:
        path: the ONNX file; keys: its input names (observation-dict keys), in the contract's order.
    """

    def __init__(self, path: Path | str, keys: tuple[str, ...]):
        try:
            import onnxruntime as ort  # type: ignore[import-untyped]
        except ImportError:
            raise InvalidConfig("running policy.onnx needs onnxruntime: pip install 'tsrl[deploy]'") from None
        options = ort.SessionOptions()
        options.intra_op_num_threads = 1
        options.inter_op_num_threads = 1
        self.session = ort.InferenceSession(str(path), options, providers=["CPUExecutionProvider"])
        names = tuple(i.name for i in self.session.get_inputs())
        if set(names) != set(keys):
            raise InvalidConfig(f"{path}: inputs {list(names)}; the contract lists {list(keys)}")
        self.keys = keys
        self._feed: dict[str, np.ndarray] = {}

    def __call__(self, inputs: Mapping[str, np.ndarray]) -> np.ndarray:
        """The action (k,) float64 of one observation: entries (d,) float64 by key."""
        feed = self._feed
        for key in self.keys:
            feed[key] = np.asarray(inputs[key], dtype=np.float64).reshape(1, -1)
        return self.session.run(None, feed)[0][0].astype(np.float64)

    def batch(self, inputs: Mapping[str, np.ndarray]) -> np.ndarray:
        """Actions (B, k) float32 of batched entries (B, d)."""
        feed = {key: np.asarray(inputs[key], dtype=np.float64) for key in self.keys}
        return np.asarray(self.session.run(None, feed)[0])

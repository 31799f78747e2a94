"""Training the heat-map CNN (needs the optional extra ``turbinefit[train]``: PyTorch, onnx).

Nothing outside this package imports PyTorch; inference uses onnxruntime
(:mod:`turbinefit.detect`).
"""

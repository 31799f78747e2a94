"""Evaluation against ground truth."""

from turbinefit.eval.metrics import Accuracy as Accuracy
from turbinefit.eval.metrics import accuracy as accuracy

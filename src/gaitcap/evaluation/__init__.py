"""``gaitcap eval``: accuracy of a tracking output against a synthetic truth or another run.

- :mod:`gaitcap.evaluation.metrics`: pure error measures (positions, swaps, angles, event matching);
- :mod:`gaitcap.evaluation.compare`: alignment and the whole comparison (:func:`evaluate`),
  thresholds;
- :mod:`gaitcap.evaluation.report`: reading the inputs, ``eval.json`` and the printed table;
- :mod:`gaitcap.evaluation.run`: a tracking output evaluated whole (the IoU, its track.json), as eval and demo write it.
"""

from gaitcap.evaluation.compare import Evaluation, Thresholds, check_thresholds, evaluate

__all__ = ["Evaluation", "Thresholds", "check_thresholds", "evaluate"]

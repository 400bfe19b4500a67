"""Type aliases shared by the modules of ffsr-gym."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

Array = npt.NDArray[np.float64]

"""What differs between the numpy versions the project runs on.

The CPU set-up pins numpy 1.26 (bpy 5.0 needs numpy < 2); GPU machines run numpy 2.x, where
``np.trapz`` is gone (removed in 2.4; ``np.trapezoid`` arrived in 2.0).
"""

from __future__ import annotations

import numpy as np

#: The composite trapezoidal rule (``np.trapezoid``, or ``np.trapz`` before numpy 2.0).
trapezoid = getattr(np, "trapezoid", None) or np.trapz

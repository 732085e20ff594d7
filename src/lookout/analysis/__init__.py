"""Analysis: stability conditions, frequency response, metrics.

Every check states its result in one vocabulary (:mod:`lookout.analysis.conditions`):
:class:`Verdict`, :class:`Inequality`, :class:`Condition`, :class:`Report`.
"""

from .conditions import Condition as Condition
from .conditions import Inequality as Inequality
from .conditions import Report as Report
from .conditions import Verdict as Verdict
from .metrics import earth_frame_velocity as earth_frame_velocity
from .metrics import estimation_errors as estimation_errors
from .metrics import fit_decay_rate as fit_decay_rate
from .metrics import rms_over as rms_over
from .metrics import settling_time as settling_time
from .passive import characteristic_frequencies as characteristic_frequencies
from .passive import check_passive_observer as check_passive_observer
from .passive import check_spr as check_spr
from .passive import check_tuning_rule as check_tuning_rule
from .passive import default_frequencies as default_frequencies
from .passive import error_loop as error_loop
from .passive import frequency_response as frequency_response
from .passive import kyp_certificate as kyp_certificate
from .passive import minimum_phase_in_band as minimum_phase_in_band
from .passive import transfer_functions as transfer_functions
from .velocity import configuration_bounds as configuration_bounds
from .velocity import velocity_observer_condition as velocity_observer_condition

"""Named, cited parameter sets. ``SETS`` maps a set's name to its factory."""

from dampersim.parameters.sets import turbine_damper_2017

SETS = {turbine_damper_2017.NAME: turbine_damper_2017.build}
DEFAULT_SET = turbine_damper_2017.NAME

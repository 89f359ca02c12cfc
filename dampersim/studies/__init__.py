"""The thesis's chapter 7 studies as reproducible functions (see :mod:`.studies`)."""

from dampersim.studies.studies import (
    STUDIES,
    additional_orders,
    mapping,
    order_rule,
    poor_performance,
    run_study,
    speed_stiffness,
    sufficient_excitation,
    table_7_1,
)

__all__ = ["STUDIES", "run_study", "order_rule", "additional_orders", "sufficient_excitation", "mapping",
           "poor_performance", "speed_stiffness", "table_7_1"]

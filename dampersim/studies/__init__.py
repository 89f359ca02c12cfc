"""The thesis's chapter 7 studies as reproducible functions (see :mod:`.studies`)."""

from dampersim.studies.studies import (
    PLANS,
    STUDIES,
    additional_orders,
    mapping,
    order_rule,
    poor_performance,
    run_study,
    speed_stiffness,
    study_cost,
    study_plan,
    sufficient_excitation,
    table_7_1,
)

__all__ = ["STUDIES", "PLANS", "run_study", "study_plan", "study_cost", "order_rule", "additional_orders", "sufficient_excitation", "mapping",
           "poor_performance", "speed_stiffness", "table_7_1"]

"""The pool build's progress estimate (``ffsr_gym_lab.pools.build.candidates_to_go``): the candidates still needed at
the admission rate so far, for the tier furthest from its count."""

from __future__ import annotations

from collections import Counter

from ffsr_gym_lab.pools.build import candidates_to_go


def test_the_estimate_is_the_slowest_tiers_shortfall_over_its_admission_rate():
    # sweep: 80 of 8,000 admitted (1 %), 120 to go -> 12,000; nutation: 50 of 8,000, 150 to go -> 24,000
    assert candidates_to_go(Counter(sweep=80, nutation=50), {"sweep": 200, "nutation": 200}, 8000) == "~24,000"
    assert candidates_to_go(Counter(sweep=80), {"sweep": 200}, 8000) == "~12,000"
    assert candidates_to_go(Counter(sweep=200, nutation=199), {"sweep": 200, "nutation": 200}, 1000) == "~5"
    assert candidates_to_go(Counter(sweep=200), {"sweep": 200}, 1000) == "~0"  # done
    assert candidates_to_go(Counter(), {"sweep": 200}, 300) == "?"  # nothing admitted yet: no rate

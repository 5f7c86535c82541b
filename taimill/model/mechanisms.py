"""Impacts and persistent contacts: the rule that sorts contacts for the dissipation
ledger (by mechanism) and for the stress-event statistics.

A contact is an **impact** while
  - its onset normal speed u̇_n (taken before its first force acts) is at least
    STRESS_MIN_UN, and
  - it is younger than IMPACT_AGE;
otherwise it is **persistent**: a ball rolling, sliding or resting on a wall or on
another ball. A *stress event* is a collision event whose contact is an impact.

How the numbers were chosen (CY jar, 12 steel balls of 6 mm, Ω = 200 rpm, 8 s runs,
window 4-8 s, seed 1; onset speeds in log bins):
  - steel-steel, K = -2.6 (cataracting): 13 491 events with onset u̇_n from 2 mm/s to
    3 m/s, durations 0.01-0.3 ms; only 15 have u̇_n < 10 mm/s (0.08 % of their stress
    energy). The events account for all of the dissipated power (4.08 of 4.07 W).
  - steel-fluorite, K = -3.0 (a bed riding the wall): 391 closed contacts, every one
    with onset u̇_n between 0.02 and 0.56 mm/s (grazing re-contacts), none above; the
    closed contacts dissipate 0.002 W of the mill's 3.3 W, the rest goes into
    contacts that never close.
The log-u̇_n spectrum is empty between 0.6 and 2 mm/s and nearly empty up to 10 mm/s,
so the threshold sits at 10 mm/s, a decade above the grazing re-contacts. The longest
impact measured lasts 0.3 ms; a contact still closed after IMPACT_AGE = 1 ms (3× that)
has become a resting or rolling one, and its dissipation from then on is persistent.
"""

STRESS_MIN_UN = 0.01  #: m/s, least onset normal speed of an impact
IMPACT_AGE = 1e-3  #: s, contacts older than this are persistent

"""Accuracy over time: the reliability of a machine whose errors drift with age
(the machine file's ``[drift]`` table, :mod:`reliability.model.drift`; docs/over-time.md).

- :mod:`.first_passage`: the probability that a linearly drifting output stays within its
  limit over a life;
- :mod:`.life_fosm`: each output at an age and over ``[0, age]`` at its worst grid pose;
- :mod:`.wear_paths`: gamma wear paths and the out-crossing (Rice) check;
- :mod:`.life_yield`: the machine yield over the life on the exact chain;
- :mod:`.recalibration`: the age at which a curve falls below a level;
- :mod:`.compensated_life`: recalibration with a compensation plan;
- :mod:`.life_check`: Monte-Carlo on the exact chain at the worst poses.
"""

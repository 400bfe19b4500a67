"""ffsr-gym's lab: the benchmark's maintenance, apart from the library users import (``ffsr_gym``).

The leaderboard's storage, tables, aggregates and figures (``board``); the task pools' builds and the frozen
reference's writing (``pools``); the per-task best-known search and its stored records (``best_known``); the RL
study's plan and the hyperparameter searches (``studies``); the docs site's generated pages and the offline
datasets (``publish``); and their sub-commands, which join ``ffsr-gym`` through the ``ffsr_gym.commands`` entry
point (``cli``). The library never imports this package.
"""

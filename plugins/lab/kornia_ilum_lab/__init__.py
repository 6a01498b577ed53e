"""kornia_ilum_lab: the lab that makes kornia_ilum's estimators.

The light stage and its lighting environments (:mod:`kornia_ilum_lab.synth`), training
(:mod:`kornia_ilum_lab.train`), the held-out evaluation (:mod:`kornia_ilum_lab.evaluation`), the paper's
ablations (:mod:`kornia_ilum_lab.ablation`) and the bench's error part (:mod:`kornia_ilum_lab.bench`). It plugs
into the library through entry points, as the estimator plugins do: its commands (``kornia-ilum synth``,
``train``, ``evaluate``, ``ablate``; :mod:`kornia_ilum_lab.commands`), the training recipe of ``ours`` and the
bench's error part. The library never imports it (an import-linter contract in ``pyproject.toml``).

Nothing is imported with this package: import the modules by name.
"""

__version__ = "0.1.0.dev0"

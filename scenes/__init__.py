"""Scene scripts: each module exposes ``build(**sizes) -> (Scene, Params)`` and ``DURATION``,
and runs itself with ``python scenes/NAME.py``. Tests and benchmarks import the builders."""

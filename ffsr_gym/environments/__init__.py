"""The Gymnasium environments (single and batched) and their rendering: thin glue over ``sim``.

The only sub-package, with ``bench`` and ``optim``, that imports gymnasium.
"""

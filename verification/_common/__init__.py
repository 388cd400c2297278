"""What the studies share: HTML pieces (:mod:`.html`), pictures (:mod:`.render`), running stages (:mod:`.run`).

This package imports no study; every study may import it.
"""

"""Robot controllers: serial drivers, their wire protocols, and simulated controllers on pseudo-terminals.

Drivers (:class:`~bench.robots.pkm5.Pkm5Controller`, :class:`~bench.robots.delta4.Delta4Controller`) receive an
open pyserial port; simulators (``python -m bench.simulators.pkm5`` / ``bench.simulators.delta4``, ``bench sim ...``) are separate
programs speaking the same wire protocol over a pty. Wire protocols: ``docs/protocol-pkm5.md``,
``docs/protocol-delta4.md``.
"""

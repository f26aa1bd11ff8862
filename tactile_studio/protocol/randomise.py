"""Per-block gesture orders, reproducible from (protocol, participant, seed).

The generator is seeded from a SHA-256 of the three, never from Python's salted
``hash``, so the same participant gets the same orders on every machine and run.
"""

from __future__ import annotations

import hashlib

import numpy as np

from tactile_studio.storage.format.protocol_file import CollectionProtocol


def order_seed(protocol: CollectionProtocol, participant: str, seed: int = 0) -> int:
    """The integer that seeds a participant's block orders."""
    text = f"{protocol.name}|{participant.strip()}|{int(protocol.seed)}|{int(seed)}"
    return int.from_bytes(hashlib.sha256(text.encode("utf-8")).digest()[:8], "little")


def block_orders(protocol: CollectionProtocol, participant: str, seed: int = 0,
                 blocks: int | None = None) -> list[list[str]]:
    """One list of gesture names per block: a fresh permutation per block
    (``shuffle_per_block``) or the file's order (``fixed``)."""
    names = protocol.gesture_names
    n = protocol.blocks if blocks is None else blocks
    if protocol.randomisation == "fixed":
        return [list(names) for _ in range(n)]
    rng = np.random.default_rng(order_seed(protocol, participant, seed))
    return [[names[i] for i in rng.permutation(len(names))] for _ in range(n)]


def practice_order(protocol: CollectionProtocol, participant: str, seed: int = 0) -> list[str]:
    """The gestures of the practice trials (cycling through a shuffled set)."""
    names = protocol.gesture_names
    rng = np.random.default_rng([order_seed(protocol, participant, seed), 0x9AC7])
    out: list[str] = []
    while len(out) < protocol.practice_trials:
        out += [names[i] for i in rng.permutation(len(names))]
    return out[: protocol.practice_trials]

"""Which gestures the collection runner still has to collect, round by round.

A session is a list of rounds: practice rounds (block -1, at most one gesture set each)
and then the blocks in their randomised orders. For each round the plan knows which
gestures are done, which scheduled breaks were taken and where a resumed session picks
up. Pure bookkeeping (no clock, no file, no device), so the runner's state machine only
asks questions of it.

The prompted gesture of a round is the first of ``remaining()``: the round's planned
order without the done gestures, except that a redone gesture comes first (it was the
last one done, so it is normally first anyway; a resumed older file may have gaps).
"""

from __future__ import annotations

from typing import Any

from tactile_studio.storage.format.trials import TrialRecord, records


class BlockPlan:
    """Practice rounds then blocks; ``index`` is the round being collected."""

    def __init__(self, orders: list[list[str]], practice: list[str], per_round: int,
                 break_every: int) -> None:
        n = per_round
        self.rounds: list[tuple[int, list[str]]] = [
            (-1, practice[i:i + n]) for i in range(0, len(practice), n)]
        self.rounds += [(b, order) for b, order in enumerate(orders)]
        self.done: list[set[str]] = [set() for _ in self.rounds]
        self.index = 0
        self.n_blocks = len(orders)
        self.break_every = break_every
        self.breaks_taken: set[int] = set()
        self.redo_first: dict[int, str] = {}  # round index -> its reopened gesture
        self.last: dict[int, list[str]] = {}  # round index -> gestures collected again last

    def restore(self, trials: list[TrialRecord] | list[dict[str, Any]]) -> None:
        """Mark the gestures of a resumed session's trials done (redone ones excepted),
        skip practice, and move to the first round with gestures left."""
        round_of = {b: i for i, (b, _) in enumerate(self.rounds) if b >= 0}
        for i, (b, gestures) in enumerate(self.rounds):
            if b < 0:
                self.done[i] = set(gestures)  # practice is not repeated on resume
        for t in records(trials):
            if t.counts and t.block in round_of:
                self.done[round_of[t.block]].add(t.gesture)
        self.index = next((i for i in range(len(self.rounds)) if self.remaining(i)),
                          len(self.rounds) - 1)
        self.breaks_taken = {b for b, _ in self.rounds if 0 <= b < self.rounds[self.index][0]}

    @property
    def block(self) -> int:
        """The current round's block (0-based; -1 for practice)."""
        return self.rounds[self.index][0]

    @property
    def gestures(self) -> list[str]:
        """The current round's gestures in their planned order."""
        return self.rounds[self.index][1]

    def remaining(self, i: int | None = None) -> list[str]:
        """Gestures of round ``i`` (default: the current one) not done yet, in the order
        they are prompted (a redone gesture first, then the planned order)."""
        i = self.index if i is None else i
        last = self.last.get(i, [])
        left = [g for g in self.rounds[i][1] if g not in self.done[i] and g not in last]
        left += [g for g in last if g not in self.done[i]]
        first = self.redo_first.get(i)
        if first in left and left[0] != first:
            left.remove(first)
            left.insert(0, first)
        return left

    @property
    def prompted(self) -> str | None:
        """The gesture the screen prompts now (None when the round is complete)."""
        left = self.remaining()
        return left[0] if left else None

    def is_done(self, gesture: str) -> bool:
        return gesture in self.done[self.index]

    def mark_done(self, gesture: str) -> None:
        self.done[self.index].add(gesture)
        if self.redo_first.get(self.index) == gesture:
            del self.redo_first[self.index]

    def reopen(self, block: int, gesture: str) -> None:
        """Put a redone trial's gesture back: its round (the latest one of ``block``
        where it is done) becomes the current round again."""
        i = next(i for i in range(min(self.index, len(self.rounds) - 1), -1, -1)
                 if self.rounds[i][0] == block and gesture in self.done[i])
        self.done[i].discard(gesture)
        self.redo_first[i] = gesture
        self.index = i

    def collect_again(self, gesture: str) -> None:
        """Put a discarded ``gesture`` of the current round back, prompted after the
        round's other gestures (a discard's "collect again at the end of the block")."""
        self.done[self.index].discard(gesture)
        last = self.last.setdefault(self.index, [])
        if gesture in last:
            last.remove(gesture)
        last.append(gesture)

    def is_last_round(self) -> bool:
        return self.index + 1 >= len(self.rounds)

    def advance(self) -> None:
        self.index += 1

    def break_after(self, block: int) -> bool:
        """True if a scheduled break follows the completion of ``block`` (0-based)."""
        k = self.break_every
        return (k > 0 and block >= 0 and (block + 1) % k == 0 and block + 1 < self.n_blocks
                and block not in self.breaks_taken)

    def take_break(self, block: int) -> None:
        self.breaks_taken.add(block)

    def rounds_ahead(self) -> list[tuple[int, list[str]]]:
        """(block, remaining gestures) of the current round and every later one."""
        return [(self.rounds[i][0], self.remaining(i)) for i in range(self.index, len(self.rounds))]

    def upcoming(self, n: int, skip: str | None = None) -> list[tuple[int, str]]:
        """The next ``n`` (block, gesture) pairs in the planned order, leaving out
        ``skip`` in the current round (the running trial)."""
        out: list[tuple[int, str]] = []
        for i in range(self.index, len(self.rounds)):
            for g in self.remaining(i):
                if i == self.index and g == skip:
                    continue
                out.append((self.rounds[i][0], g))
                if len(out) >= n:
                    return out
        return out

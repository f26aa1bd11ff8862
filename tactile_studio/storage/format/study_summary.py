"""What a folder of sessions adds up to, as a study: who, on what, how many of each
gesture, and who is missing a gesture the others performed.

An experimenter checks this after importing or collecting a study and before training:
a participant without any ok trial of a gesture is tested on a class they never
performed in training's eyes, and a leave-one-participant-out figure quietly changes.
Shared by ``tactile-studio info DIR`` and the research workspace's Sessions tab.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterable
from dataclasses import dataclass, field


@dataclass
class StudyCounts:
    participants: list[str] = field(default_factory=list)
    conditions: dict[str, int] = field(default_factory=dict)  # condition -> sessions
    per_gesture: dict[str, int] = field(default_factory=dict)  # gesture -> ok trials
    missing: dict[str, list[str]] = field(default_factory=dict)  # participant -> gestures

    @property
    def ok_trials(self) -> int:
        return sum(self.per_gesture.values())

    def lines(self) -> list[str]:
        """The study in a few lines (nothing for an empty study)."""
        if not self.participants:
            return []
        people = self.participants
        shown = ", ".join(people) if len(people) <= 6 else f"{people[0]} … {people[-1]}"
        out = [f"participants: {len(people)} ({shown})"]
        if self.conditions:
            out.append("conditions: " + ", ".join(
                f"{c or '(none)'} {n} session(s)" for c, n in sorted(self.conditions.items())))
        counts = sorted(set(self.per_gesture.values()))
        if not counts:  # sessions, but no ok trial in any (all aborted early)
            out.append("ok trials: 0")
            return out
        spread = (f"{counts[0]} each" if len(counts) == 1
                  else f"{counts[0]}-{counts[-1]}; fewer than {counts[-1]}: " + ", ".join(
                      f"{g} {n}" for g, n in self.per_gesture.items() if n < counts[-1]))
        out.append(f"ok trials: {self.ok_trials} of {len(self.per_gesture)} gestures ({spread})")
        out += [f"{person} has no ok trial of {', '.join(gestures)}"
                for person, gestures in self.missing.items()]
        return out

    def missing_text(self, people: int = 3) -> str:
        """The gaps in one short line ("" when none): the first ``people``, then a count."""
        gaps = [f"{p} has no {', '.join(g)}" for p, g in self.missing.items()]
        more = len(gaps) - people
        return "; ".join(gaps[:people]) + (f"; {more} more" if more > 0 else "")


def study_counts(sessions: Iterable[tuple[str, str, dict[str, int]]]) -> StudyCounts:
    """``sessions``: (participant, condition, ok trials per gesture) per session file;
    one without a participant (a plain recording) is no part of a study."""
    per_person: dict[str, Counter] = {}
    conditions: Counter = Counter()
    total: Counter = Counter()
    for participant, condition, per_gesture in sessions:
        if not participant:
            continue
        per_person.setdefault(participant, Counter()).update(per_gesture)
        conditions[condition or ""] += 1
        total.update(per_gesture)
    gestures = sorted(g for g, n in total.items() if n > 0)
    missing = {p: [g for g in gestures if counts[g] == 0]
               for p, counts in sorted(per_person.items())}
    return StudyCounts(
        participants=sorted(per_person),
        conditions=dict(conditions) if set(conditions) != {""} else {},
        per_gesture={g: total[g] for g in gestures},
        missing={p: g for p, g in missing.items() if g})

"""Kinds of a sweep's jobs not timed yet, timed by kinds shown to cost as much (launch.time_left): a kind is its
swept values but the seed, and two timed kinds that differ in one key alone show whether that key changes a job's
work."""

from __future__ import annotations

import statistics

SAME = 1.5  # two kinds' work within this factor...
SLACK = 1.0  # ...and this many seconds: the one swept value they differ in does not change a job's time
PAIRS = 200  # timed kinds at most whose pairs are compared (a sweep of hundreds of kinds: no borrowing)
# swept keys that choose which recordings a job reads (a fault, a sensor, a car, a road class), not how many or
# what is fitted to them: taken not to change a job's time until two timed kinds show otherwise
DATA_KEYS = frozenset({"fault", "sensor", "car", "road"})


def _parts(kind: str) -> dict[str, str]:
    return dict(part.partition("=")[::2] for part in kind.split(" ") if part)


def borrowed(
    means: dict[str, float],
    wanted: set[str],
    works: dict[str, float],
    networks: frozenset = frozenset(),
    cpus: dict[str, float] | None = None,
    guess: bool = False,
) -> dict[str, float]:
    """Kinds of ``wanted`` timed by those of ``means`` that differ from them only in keys shown not to change a
    job's time: every two timed kinds that differ in that key alone did as much work (``cpus``, the CPU time of
    their work, where both have it, since load on the machine moves wall time; else ``works``, else ``means``:
    within SAME and SLACK). So once a baseline's fits under two faults took as long, a network under the second
    fault takes its time under the first. Work, not a job's time: the first jobs under a new fault also load its
    dataset, once. Failing that, a kind one value away that picks the recordings (``DATA_KEYS``), or one value
    away in any key from a kind of ``networks`` (its jobs train), where no two timed kinds showed that key to
    matter. A key is judged by the pairs that share a kind's other values where there are any (a fault's fixed fit
    may take longer than under another fault, the plain fit not), else, for a key that picks the recordings, by
    pairs of networks for networks and of the rest for the rest (a network trains its steps either way). With
    ``guess``, a kind none of these times takes the mean of its kinds one value away in a key that picks the
    recordings, even where that key was shown to matter: a guess, which the job line says as such."""
    if not wanted or len(means) > PAIRS:
        return {}
    parts = {k: _parts(k) for k in {*means, *wanted}}

    def differ(a: str, b: str) -> set[str] | None:
        return {k for k in parts[a] if parts[a][k] != parts[b][k]} if parts[a].keys() == parts[b].keys() else None

    same: dict = {}  # a key -> as much work; a key that picks the recordings: (key, networks or not) -> the same
    own: dict = {}  # (a key, the other keys' values) -> as much work, for the pairs that share those values
    timed = sorted(means)

    def rest(kind: str, key: str) -> frozenset:
        return frozenset((k, v) for k, v in parts[kind].items() if k != key)

    for i, a in enumerate(timed):
        for b in timed[i + 1 :]:
            keys = differ(a, b)
            if keys is not None and len(keys) == 1:
                # a network under one fault trained 183 s beside other work against 352 s idle under another
                both = cpus if cpus and a in cpus and b in cpus else works
                low, high = sorted((both.get(a, means[a]), both.get(b, means[b])))
                key, alike = next(iter(keys)), high <= SAME * low + SLACK
                own[key, rest(a, key)] = own.get((key, rest(a, key)), True) and alike
                if key in DATA_KEYS:
                    if (a in networks) != (b in networks):
                        continue
                    key = (key, a in networks)
                same[key] = same.get(key, True) and alike

    def shown(key: str, t: str) -> bool | None:
        """Whether the timed pairs showed ``key`` not to change the work of a job like ``t`` (None: no pair): the
        pairs of its own other values where there are any (the fault changes a fixed fit's time, not the plain
        fit's), else, for a key that picks the recordings, those of networks or of fits, as ``t`` is."""
        if (key, rest(t, key)) in own:
            return own[key, rest(t, key)]
        return same.get((key, t in networks) if key in DATA_KEYS else key)

    out = {}
    for kind in wanted:
        # a baseline's time lends itself across a key that picks recordings alone: two baselines as fast do not show
        # that a network chosen by the same key is (experiment=anchored_clean said "about 0:08" with 13:04 left)
        near = [
            means[t]
            for t in timed
            if (keys := differ(kind, t)) and all(shown(k, t) for k in keys) and (keys <= DATA_KEYS or t in networks)
        ]
        # else a kind one value away in a key that picks the recordings, not the work (``DATA_KEYS``), where no two
        # timed kinds showed that key to matter: a sweep over the fault alone has no such pair until a second
        # fault ends, and its first fault's time is the best guess for the rest
        # or a network's sibling in another key: the main job's three objectives train the same network the same
        # steps, and the first objective's wave said "at least 0:00" with 2:12 left until the next reported steps
        near = near or [
            means[t]
            for t in timed
            if (keys := differ(kind, t))
            and len(keys) == 1
            and (keys <= DATA_KEYS or t in networks)
            and shown(next(iter(keys)), t) is None
        ]
        # with guess: the same kind under the other faults, though they differ (the anchored sweep's lowpass and
        # hardening faults after three others said "at least 0:04" with about 3 h 30 min left)
        near = near or [
            means[t] for t in timed if guess and (keys := differ(kind, t)) and len(keys) == 1 and keys <= DATA_KEYS
        ]
        if near:
            out[kind] = statistics.fmean(near)
    return out

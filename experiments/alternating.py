"""Child processes of an experiment under several settings, alternating, so that the machine's drift falls on all.

``python SCRIPT --child ...`` prints one JSON object per line for each timed call; :func:`alternate` runs it once
per setting per pair, each with its environment changes, and gathers the rows labelled with the setting and the
pair. Used by ``thread_wait.py`` (OpenMP's wait policy), ``floor.py`` and ``one_command.py`` (another checkout's
code). :class:`Clock` times the calls a child makes, by category, through wrappers on them.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
import time
from collections import defaultdict


def compared_commit(checkout) -> str | None:
    """The commit a ``--compare`` checkout is at: its short hash and subject, the subject shortened to 80 characters
    at a word (a cut name would read as another); None without a checkout."""
    if checkout is None:
        return None
    line = subprocess.run(["git", "-C", str(checkout), "log", "-1", "--format=%h %s"], capture_output=True,
                          text=True).stdout.strip()
    return textwrap.shorten(line, 80, placeholder=" …") or None


class Clock:
    """Seconds spent in the wrapped calls, by category (``s``)."""

    def __init__(self):
        self.s = defaultdict(float)

    def wrap(self, owner, name, category):
        """Replace ``owner.name`` (a module's function or a class's method) by a timed call that adds its seconds to
        ``category`` (a string, or a function of the call's arguments giving one); returns ``(owner, name, f)``,
        the original, to put back."""
        f = getattr(owner, name)

        def timed_call(*args, **kwargs):
            t0 = time.perf_counter()
            try:
                return f(*args, **kwargs)
            finally:
                self.s[category(args) if callable(category) else category] += time.perf_counter() - t0
        setattr(owner, name, timed_call)
        return owner, name, f


def alternate(script, argv, settings: dict, pairs: int, label: str, reverse_odd: bool = False) -> list:
    """Rows of ``script --child`` run once per setting and pair.

    Parameters
    ----------
    script : path of the experiment
    argv : list of str
        Its arguments (``--child`` is added).
    settings : dict
        Name -> environment changes (a value of None removes the variable).
    pairs : int
        Rounds over the settings.
    label : str
        The rows' key for the setting's name (the pair's is ``pair``).
    reverse_odd : bool
        Odd rounds run the settings in reverse (A B B A ...).

    Returns
    -------
    list of dict
    """
    rows = []
    for pair in range(pairs):
        items = list(settings.items())
        for name, changes in (reversed(items) if reverse_odd and pair % 2 else items):
            env = dict(os.environ)
            for k, v in changes.items():
                if v is None:
                    env.pop(k, None)
                else:
                    env[k] = v
            out = subprocess.run([sys.executable, str(script), *map(str, argv), "--child"], env=env,
                                 capture_output=True, text=True, check=True).stdout
            rows += [dict(json.loads(line), **{label: name}, pair=pair) for line in out.splitlines()
                     if line.startswith("{")]
            print(f"pair {pair} {name}: {len(rows)} rows", flush=True)
    return rows

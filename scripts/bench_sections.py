"""Helpers shared by the scripts that write a section of BENCHMARKS.md by running Jello against a
peer (scripts/frame_rate.py, scripts/pile_bench.py), and the list of the sections that
scripts/benchmarks.py keeps when it rewrites the file. Standard library only."""

import os

# (begin prefix, end marker) of the sections written by other scripts or by hand, in the order
# they come in the file after the sections scripts/benchmarks.py writes.
KEPT = [
    ("<!-- frame-rate: begin", "<!-- frame-rate: end -->"),  # scripts/frame_rate.py
    ("<!-- pile: begin", "<!-- pile: end -->"),  # scripts/pile_bench.py
    ("<!-- contact-share: begin", "<!-- contact-share: end -->"),  # scripts/contact_share.py
    ("<!-- by hand: begin", "<!-- by hand: end -->"),  # kept by hand
]


def kept_sections(text):
    """The sections of KEPT that `text` holds, each from its begin marker to its end marker."""
    out = []
    for begin, end in KEPT:
        if begin in text and end in text:
            out.append(text[text.index(begin):text.index(end) + len(end)])
    return out


def failure(p):
    """The message of a failed command: its first line that says error, else its last line."""
    lines = (p.stderr or p.stdout).strip().splitlines() or ["exit code %d" % p.returncode]
    return next((ln for ln in lines if "error" in ln.lower()), lines[-1])


def fmt_rt(r):
    """A real-time factor as a table shows it: 3 significant digits, ¹ when the run was cut."""
    if "error" in r:
        return "failed"
    x = r["realtime"]
    s = ("%.3g" % x) if x >= 0.01 else ("%.2g" % x)
    return s + "×" + (" ¹" if r.get("capped") else "")


def rapier_version(runs):
    """The rapier3d version a list of peer results reports ("not run" when none does)."""
    for c in runs:
        if c.get("peer") == "rapier":
            return c.get("version", "?")
    return "not run"


def write_section(out, section, begin, end):
    """Replaces the section of `out` between `begin` and `end` (markers included) by `section`,
    atomically. A missing section goes where KEPT puts it: before the first kept section that
    follows it in KEPT and is in the file, else at the end."""
    text = open(out).read() if os.path.exists(out) else ""
    if begin in text and end in text:
        head, rest = text.split(begin, 1)
        tail = rest.split(end, 1)[1].lstrip("\n")
        text = head + section + ("\n" + tail if tail else "")
    else:
        names = [b for b, _ in KEPT]
        later = names[names.index(next(b for b in names if begin.startswith(b))) + 1:] \
            if any(begin.startswith(b) for b in names) else []
        at = min((text.index(b) for b in later if b in text), default=None)
        if at is None:
            text = text.rstrip("\n") + ("\n\n" if text else "") + section
        else:
            text = text[:at] + section + "\n" + text[at:]
    tmp = out + ".tmp"
    with open(tmp, "w") as f:
        f.write(text)
    os.replace(tmp, out)

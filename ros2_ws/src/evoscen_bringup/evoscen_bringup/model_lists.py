"""The installed SUT models and the SUT mutants as ``run_scenario.py --list-suts`` and ``--list-mutants``
print them (docs/plugins.md, "Registration"; docs/mutants.md): one line each, in aligned columns."""

from __future__ import annotations


def list_suts() -> list[str]:
    """One line per SUT model: name, where it comes from, description; then the entry points that failed to load."""
    from evoscen_sim.model_registry import broken_plugins, get_model, model_names, model_source

    names = model_names("sut")
    rows = [(n, model_source(n), get_model(n, "sut").description) for n in names]
    width = [max(len(r[i]) for r in rows) for i in (0, 1)]
    lines = [f"{n:<{width[0]}}  {src:<{width[1]}}  {desc}".rstrip() for n, src, desc in rows]
    lines += [f"{n:<{width[0]}}  failed to load: {why}" for n, why in sorted(broken_plugins().items())]
    return lines


def list_mutants() -> list[str]:
    """One line per mutant of the library (``evoscen_sut.mutants``): name, class, the installed SUT models
    it applies to (:func:`~evoscen_sut.mutants.applicable_bases`), description (its first sentence)."""
    from evoscen_sim.model_registry import model_names
    from evoscen_sut import mutants

    every = [n for n in model_names("sut") if n != "mutant"]
    lines = []
    for m in mutants.LIBRARY.values():
        bases = [b for b in mutants.applicable_bases(m.name) if b in every]
        desc = m.description.split(": ")[0].split(". ")[0].rstrip(".")
        lines.append((m.name, "built-in (evoscen_sut.mutants)", m.klass,
                      "bases: " + (", ".join(bases) if bases != every else f"any SUT model ({len(every)})"), desc))
    width = [max(len(r[i]) for r in lines) for i in range(4)]
    return [f"{a:<{width[0]}}  {b:<{width[1]}}  {c:<{width[2]}}  {d:<{width[3]}}  {e}" for a, b, c, d, e in lines]

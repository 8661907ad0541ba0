"""A sweep over a user's recordings without labels measures each estimate against a fit, not the truth: its
summary must say so, and a sweep with labels must not."""

import json

from hybrid_sysid.report.summary import write_summary

from helpers.evaluation_fakes import make_run


def _sweep(root, reference_of):
    for i, objective in enumerate(("hybrid", "label_free")):
        for seed in (0, 1):
            run = make_run(root / f"{i}{seed}", [f"objective={objective}", f"seed={seed}"], seed)
            record = json.loads((run / "metrics.json").read_text())
            if reference_of(objective) is not None:
                record["reference"] = reference_of(objective)
            (run / "metrics.json").write_text(json.dumps(record))
    return root


def test_a_summary_of_runs_without_labels_names_their_reference_and_only_theirs(tmp_path):
    sweep = _sweep(tmp_path / "sweep", lambda o: "fit over the whole recording" if o == "hybrid" else "labels")
    df, _ = write_summary(sweep, figures=False)
    text = (sweep / "summary.md").read_text()
    notes = [line for line in text.splitlines() if line.startswith("Deviations from the")]
    assert len(notes) == 1 and "fit over the whole recording" in notes[0], notes
    assert "`00`" in notes[0] and "`01`" in notes[0] and "`10`" not in notes[0] and "`11`" not in notes[0]
    assert set(df.reference) == {"fit over the whole recording", "labels"}  # the long form keeps it per row


def test_a_summary_of_labelled_runs_and_of_records_before_the_field_has_no_such_note(tmp_path):
    sweep = _sweep(tmp_path / "sweep", lambda o: None)
    df, _ = write_summary(sweep, figures=False)
    assert "Deviations from the" not in (sweep / "summary.md").read_text()
    assert set(df.reference) == {"labels"}


def test_a_received_records_reference_is_one_short_line(tmp_path):
    sweep = _sweep(tmp_path / "sweep", lambda o: "a fit\n" + "x" * 500 if o == "hybrid" else None)
    df, _ = write_summary(sweep, figures=False)
    note = next(line for line in (sweep / "summary.md").read_text().splitlines() if line.startswith("Deviations"))
    assert "\n" not in df.reference.iloc[0] and len(df.reference.iloc[0]) <= 80 and len(note) < 200

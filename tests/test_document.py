"""The report document's two renderers (ionav_viz.analysis.document), on golden strings written by hand."""

from __future__ import annotations

from ionav_viz.analysis.document import Code, Document, Heading, Items, Paragraphs, Table, to_markdown, to_text

TABLE = Table(["Drive", "outages", "final m"], [["a", "3", "1.50"], ["bb", "12", "-"]], 1, align=True)


def test_a_table_as_text_keys_left_values_right_under_a_rule():
    assert to_text(Document([TABLE])) == (
        "Drive  outages  final m\n"
        "-----  -------  -------\n"
        "a            3     1.50\n"
        "bb          12        -\n"
    )


def test_a_table_too_wide_is_split_into_blocks_that_repeat_the_keys():
    assert to_text(Document([TABLE]), width=16) == (
        "Drive  outages\n"
        "-----  -------\n"
        "a            3\n"
        "bb          12\n"
        "\n"
        "       final\n"
        "Drive      m\n"
        "-----  -----\n"
        "a       1.50\n"
        "bb         -\n"
    )


def test_a_table_that_cannot_be_split_is_kept_whole():
    """Fewer than two value columns: nothing to split into blocks (this raised UnboundLocalError,
    and ``compare`` at COLUMNS=40 printed a traceback)."""
    keys_only = Table(["Run", "file"], [["own", "runs/own.json"]], 2)
    assert to_text(Document([keys_only], hang=None), width=10) == "Run  file\n---  -------------\nown  runs/own.json\n"
    one_value = Table(["Run", "file"], [["own", "runs/own.json"]], 1)
    assert to_text(Document([one_value], hang=None), width=10) == (
        "Run           file\n---  -------------\nown  runs/own.json\n")


def test_a_table_as_markdown():
    assert to_markdown(Document([TABLE])) == (
        "| Drive | outages | final m |\n"
        "|---|---:|---:|\n"
        "| a | 3 | 1.50 |\n"
        "| bb | 12 | - |\n"
    )
    plain = Table(["Estimator", "Run", "n"], [["INS DR", "old", "3"], ["", "new", "4"]], 2, strong_first=True,
                  repeat_keys=True)
    assert to_markdown(Document([plain])) == (
        "| Estimator | Run | n |\n"
        "|---|---|---|\n"
        "| **INS DR** | old | 3 |\n"
        "| **INS DR** | new | 4 |\n"
    )


def test_headings_lists_and_paragraphs_in_both_forms():
    doc = Document([Heading("Worst", 2), Items([("a: 1 m; replay: ", Code("ionav-viz replay a"))], numbered=True),
                    Heading("Drift", note="(m)", lead_in=True), Items(["x", "y"]), Paragraphs(["one", "two"])])
    assert to_text(doc) == ("Worst\n\n1. a: 1 m; replay: ionav-viz replay a\n\nDrift (m):\n\nx\ny\n\none\ntwo\n")
    assert to_markdown(doc) == ("## Worst\n\n1. a: 1 m; replay: `ionav-viz replay a`\n\n**Drift** (m)\n\n"
                                "- x\n- y\n\none\n\ntwo\n")
    unspaced = Document([Heading("Title"), Paragraphs(["alpha beta gamma"])], spaced=False, hang=2)
    assert to_text(unspaced, width=11) == "Title\nalpha beta\n  gamma\n"
    assert to_text(Document([Paragraphs(["alpha beta gamma"])], hang=None), width=11) == "alpha beta gamma\n"


def test_a_drive_reports_line_on_its_real_losses_is_a_paragraph_of_its_own():
    """As Markdown the mean over the log's own GNSS losses ran on into the next line (the GNSS
    truth's) as one paragraph; each is a paragraph of its own, as the report's other lines."""
    import ionav_viz as iv

    report = iv.evaluate(iv.Experiment(["V-sim-motorway-tunnels"], 10.0, iv.AroundEvents(("gnss-outage",)),
                                       run=iv.RunOptions(estimators=["ins", "odo"])))
    lines = report.to_markdown().splitlines()
    mean = next(i for i, line in enumerate(lines) if line.startswith("Mean final position error over"))
    assert lines[mean + 1] == "" and lines[mean + 2].startswith("GNSS truth:")
    text = report.to_text().splitlines()  # as text: one line after the other
    mean = next(i for i, line in enumerate(text) if line.startswith("Mean final position error over"))
    assert text[mean + 1].startswith("GNSS truth:")

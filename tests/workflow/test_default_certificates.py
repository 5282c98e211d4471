"""The default run's certificates: every ISO/IEC 17025 item, the DCC read back, signed with a
throw-away key, verified unsigned, and any tampered copy refused (the run: tests/conftest.py,
``thesis_run``)."""

import json
import re

FIELDS = (  # ISO/IEC 17025:2017 7.8.2.1 and 7.8.4.1: each a cell of the certificate's first table
    "laboratory",
    "address",
    "accreditation",
    "customer",
    "item",
    "serial_number",
    "calibrated",
    "issued",
    "method",
    "environment",
    "traceability",
    "approver",
)


def test_every_default_certificate_states_iso_17025_its_dcc_holds_and_signs(
    thesis_run, tmp_path, monkeypatch
):
    """Each default campaign's certificate: every 7.8 item present and not empty, its number,
    "unsigned" and "page x of y" on every PDF page (no key in a default run); its DCC valid
    against PTB's schema and read back by dcc-json-toolkit equal to summary.json, figure for
    figure; then made again with a throw-away lab key, verified against its CA."""
    from dcc_check import read_back, results_read_back, schema_errors
    from pdf_check import page_texts
    from throwaway_pki import make

    from calflow.cli import main

    certificates = sorted(thesis_run.glob("reports/*/certificate.html"))
    assert len(certificates) >= 9
    (tmp_path / "pki").mkdir()
    pki = make(tmp_path / "pki")
    for html_file in certificates:
        name = html_file.parent.name
        html = html_file.read_text()
        for field in FIELDS:
            start = html.index(f'data-field="{field}"')
            cell = re.sub(
                r"<[^>]+>", "", html[html.index(">", start) + 1 : html.index("</td>", start)]
            ).strip()
            assert cell and cell != "—", (name, field)
        number = re.search(r'data-number="([^"]+)"', html).group(1)
        pages = page_texts(html_file.with_suffix(".pdf"))
        for i, text in enumerate(pages, 1):
            assert number in text and "UNSIGNED" in text and f"page {i} of {len(pages)}" in text, (name, i)
        xml = html_file.with_suffix(".xml").read_bytes()
        assert schema_errors(xml, tmp_path) == [], name
        summary = json.loads((thesis_run / f"results/{name}/summary.json").read_text())
        for key, (value, U, k, _) in results_read_back(read_back(xml, tmp_path)).items():
            parent_key, leaf = key.rsplit(".", 1)
            parent = summary
            for part in parent_key.split("."):
                parent = parent[part]
            assert value == parent[leaf], (name, key)
            if U is not None:
                assert (U, k) == (parent["uncertainty"][leaf]["U"], parent["uncertainty"][leaf]["k"]), (
                    name,
                    key,
                )
        # signed: the same certificate made with a lab key outside the project
        out = tmp_path / name
        out.mkdir()
        monkeypatch.chdir(thesis_run)
        monkeypatch.setenv("CALFLOW_SIGNING_KEY", str(pki["p12"]))
        monkeypatch.setenv("CALFLOW_SIGNING_PASSWORD", pki["password"])
        args = [
            "certificate",
            "--campaign",
            f"config/campaigns/{name}.yaml",
            "--summary",
            f"results/{name}/summary.json",
        ]
        args += ["--html", str(out / "c.html"), "--pdf", str(out / "c.pdf"), "--xml", str(out / "c.xml")]
        assert main(args) == 0, name
        for suffix in ("pdf", "xml"):
            check = ["verify-certificate", str(out / f"c.{suffix}"), "--trust", str(pki["ca"])]
            assert main([*check, "--summary", f"results/{name}/summary.json"]) == 0, (name, suffix)


def test_every_default_certificate_verifies_unsigned_and_refuses_a_tampered_pdf_dcc_or_summary(
    thesis_run, tmp_path, monkeypatch, capsys
):
    """A newcomer's default run (no key): each certificate's PDF and DCC verify on their
    values and say "unsigned"; one digit changed in the PDF's printed text (the DCC inside
    left alone), in the DCC, or in the summary is refused in one line naming what differs."""
    import shutil

    from pdf_check import change_text

    from calflow.certificate.document import rows
    from calflow.cli import main

    def bump(text: str) -> str:  # its last decimal digit one up
        j = max(i for i, ch in enumerate(text) if ch.isdigit())
        return text[:j] + str((int(text[j]) + 1) % 10) + text[j + 1 :]

    monkeypatch.chdir(thesis_run)
    monkeypatch.delenv("CALFLOW_SIGNING_KEY", raising=False)
    certificates = sorted(thesis_run.glob("reports/*/certificate.pdf"))
    assert len(certificates) >= 9
    for pdf_file in certificates:
        name = pdf_file.parent.name
        summary_file = f"results/{name}/summary.json"
        summary = json.loads((thesis_run / summary_file).read_text())
        for suffix in ("pdf", "xml"):
            assert main(["verify-certificate", f"reports/{name}/certificate.{suffix}"]) == 0, (name, suffix)
            assert capsys.readouterr().out.rstrip().endswith("; unsigned"), (name, suffix)
        # the printed text: the first result's value, or (no result with a U) the number
        with_u = [r for r in rows(summary) if r["uncertainty"] and isinstance(r["value"], (int, float))]
        pdf = pdf_file.read_bytes()
        if with_u:  # (drawn in its row, or its budget's caption if the row's cell wraps it)
            shown = f"{with_u[0]['value']:.4f}"
            what = bump(shown)  # the refusal quotes what the page shows
        else:
            shown = re.search(r'data-number="([^"]+)"', pdf_file.with_suffix(".html").read_text())[1]
            what = "certificate number"
        out = tmp_path / name
        out.mkdir()
        (out / "t.pdf").write_bytes(change_text(pdf, shown, bump(shown)))
        xml = pdf_file.with_suffix(".xml").read_text()
        at = xml.find("<dcc:results")  # the first result's value (not an influence condition's)
        # its leading digit: a last digit of 17 may leave the double unchanged
        value = re.compile(r"<si:value>-?(\d)").search(xml, max(at, 0))
        if value:  # (a DCC of no result has none)
            (out / "t.xml").write_text(xml[: value.start(1)] + bump(value[1]) + xml[value.end(1) :])
        text = (thesis_run / summary_file).read_text()
        first = re.search(r'"accuracy_um": (-?\d+\.\d+)', text) or re.search(r": (\d+\.\d+)", text)
        j = first.start(1) + first[1].startswith("-")  # its leading digit, as in the DCC
        (out / "s.json").write_text(text[:j] + bump(text[j]) + text[j + 1 :])
        shutil.copy(pdf_file.with_suffix(".xml"), out / "c.xml")
        for tampered, summary_arg, names in (
            (out / "t.pdf", summary_file, what),
            (out / "t.xml", summary_file, "result " if with_u else "certificate"),
            (out / "c.xml", str(out / "s.json"), ""),
        ):
            if tampered.suffix == ".xml" and not with_u and summary_arg == summary_file:
                continue  # a DCC of no result has no value to change
            assert main(["verify-certificate", str(tampered), "--summary", summary_arg]) != 0, (
                name,
                tampered,
            )
            err = capsys.readouterr().err.strip()
            assert len(err.splitlines()) == 1 and names in err, (name, tampered, err)

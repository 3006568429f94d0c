"""The papers' claims from the run's CSVs, the report's captions and front page (rule write_claims)."""

from pathlib import Path

from brdfpipe.core import integrity
from brdfpipe.core.logutil import log_to
from brdfpipe.core.notes import read_note
from brdfpipe.report import captions, claims, runinfo, sidebyside

with log_to(snakemake.log[0], stamp=snakemake.input.stamp):
    inp = snakemake.input
    found = claims.compute_claims(
        claims.ClaimInputs(
            errors=inp.errors,
            training_size=inp.training_size or None,
            fig08_table=inp.fig08_table[0] if inp.fig08_table else None,
            paper_directions=inp.paper_directions or None,
            reproduction=inp.reproduction,
            spaces=inp.spaces,
            paths=inp.paths,
            traces=dict(zip(snakemake.params.latent_dims, inp.traces)),
            bounce_shares=inp.bounce_shares,
            errormap_summary=inp.errormap_summary or None,
            floor_check=inp.floor_check or None,
            closedloop=inp.closedloop or None,
            unseen=inp.unseen or None,
            unseen_albedo=list(inp.unseen_albedo),
        )
    )
    # other databases' recorded runs, shown beside this run's claims (config report.compare_with; read at parse time)
    recorded = [claims.RunClaims(Path(r["source"]), r["rows"], r["source"]) for r in snakemake.params.recorded]
    claims.write_claims(
        found,
        csv_path=snakemake.output.claims,
        json_path=snakemake.output.json,
        rst_path=snakemake.output.rst,
        recorded=recorded,
    )
    sidebyside.write_run_page(snakemake.output.fidelity, claims_csv=snakemake.output.claims, recorded=recorded)
    splits = integrity.read_json(inp.splits, kind="splits file")  # its digest checked
    notes = {k: read_note(f) for k, f in zip(snakemake.params.note_keys, inp.notes)}  # digests checked
    captions.write_captions(snakemake.params.entries, found,
                            database=splits.get("database_title") or splits["database"], notes=notes)
    runinfo.write_front(
        snakemake.output.front,
        claims=found,
        splits=splits,
        config=snakemake.params.config,
        configfiles=snakemake.params.configfiles,
        targets=snakemake.params.targets,
        versions=runinfo.versions(),
        recorded=recorded,
    )

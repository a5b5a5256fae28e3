"""Artefacts: design results on disk (schema ``tanksynth.artefact/1``), written atomically."""

from __future__ import annotations

from tanksynth._lazy import lazy_exports as _lazy_exports

#: Re-exported name -> its module, imported on first use (PEP 562): importing the package
#: loads none of its modules' dependencies (issue 15).
_EXPORTS = {
    "c_header": "tanksynth.artefacts.export",
    **dict.fromkeys(["EXPORT_FORMATS", "PLANT_SCHEMA", "SCHEMA", "artefact_document",
                     "gains_digest", "load_artefact", "read_artefact", "read_plant_record",
                     "to_jsonable", "write_artefact", "write_plant_record"],
                    "tanksynth.artefacts.io"),
    **dict.fromkeys(["Artefact", "Gains", "Provenance", "Verification", "VerificationCheck"],
                    "tanksynth.artefacts.model"),
}

__getattr__, __dir__ = _lazy_exports(__name__, _EXPORTS)

__all__ = ["SCHEMA", "PLANT_SCHEMA", "EXPORT_FORMATS", "write_plant_record", "read_plant_record",
           "to_jsonable", "gains_digest", "artefact_document", "write_artefact", "read_artefact",
           "load_artefact", "c_header", "Artefact", "Gains", "Provenance", "Verification",
           "VerificationCheck"]

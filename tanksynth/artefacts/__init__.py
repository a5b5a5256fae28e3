"""Artefacts: design results on disk (schema ``tanksynth.artefact/1``), written atomically."""

from __future__ import annotations

from tanksynth.artefacts.export import c_header
from tanksynth.artefacts.io import (EXPORT_FORMATS, PLANT_SCHEMA, SCHEMA, artefact_document,
                                    gains_digest, read_artefact, read_plant_record,
                                    to_jsonable, write_artefact, write_plant_record)

__all__ = ["SCHEMA", "PLANT_SCHEMA", "EXPORT_FORMATS", "write_plant_record", "read_plant_record",
           "to_jsonable", "gains_digest", "artefact_document", "write_artefact", "read_artefact",
           "c_header"]

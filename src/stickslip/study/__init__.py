"""Studies: YAML files that say which model to simulate, which theory to compare and what to
write (`stickslip run STUDY.yaml --out DIR`, or `stickslip.run_study`)."""

from .fitting import run_fit
from .load import StudyError, load_study
from .run import run_study
from .schema import Study


def study_schema() -> dict:
    """The JSON schema of a study file."""
    return Study.model_json_schema()


__all__ = ["Study", "StudyError", "load_study", "run_fit", "run_study", "study_schema"]

"""Monte Carlo experiments: sweeps of simulated flights, the paper's studies, reports."""

from turbinefit.experiments.studies import STUDIES as STUDIES
from turbinefit.experiments.studies import run_study as run_study
from turbinefit.experiments.studies import study_config as study_config
from turbinefit.experiments.studies import write_report as write_report
from turbinefit.experiments.sweep import SweepConfig as SweepConfig
from turbinefit.experiments.sweep import read_rows as read_rows
from turbinefit.experiments.sweep import run_sweep as run_sweep

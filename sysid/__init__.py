"""Fit the walker to measured walks, sample the posterior, and name what the model lacks.

The main functions and result types by name (loaded on first use, PEP 562, so that importing the
package does not build the model's compiled functions):

- :class:`FitResult`, :func:`periodicity_test` (:class:`PeriodicityTest`), :func:`multi_start`;
  the fit itself is :func:`toywalk.sysid.fit.fit` and the sampler
  :func:`toywalk.sysid.sample.sample` (:class:`SampleSummary`): their modules have their names,
  and once a module is imported the package's attribute of that name is the module;
- :func:`diagnose` (:class:`Diagnosis`), :func:`diagnose_walks` (:class:`WalksDiagnosis`),
  :func:`diagnose_summary` (:class:`SummaryDiagnosis`, from :func:`read_summary`'s numbers);
  the naming rule they share (:func:`decide`, :func:`judge`, :func:`candidates`);
- :func:`observations`, the measured walk arranged for fitting.

The modules: :mod:`~toywalk.sysid.fit` (its problem, :mod:`~toywalk.sysid.problem`; its result,
:mod:`~toywalk.sysid.fitresult`; score tests at it, :mod:`~toywalk.sysid.score`),
:mod:`~toywalk.sysid.sample`,
:mod:`~toywalk.sysid.discrepancy` (one walk), :mod:`~toywalk.sysid.walks` (several),
:mod:`~toywalk.sysid.summary` (summary numbers), :mod:`~toywalk.sysid.naming` (the rule),
:mod:`~toywalk.sysid.residuals`, :mod:`~toywalk.sysid.design` (which walk to film next), and the
command line, :mod:`~toywalk.sysid.cli`.
"""

from toywalk.model.exports import lazy_names

#: Each public name and the submodule that defines it.
_WHERE = {
    "Candidate": "naming",
    "DiagnoseError": "naming",
    "Diagnosis": "discrepancy",
    "FitError": "problem",
    "FitResult": "fitresult",
    "MeasurementError": "measurement",
    "PeriodicityTest": "fit",
    "SampleError": "sample",
    "SampleSummary": "sample",
    "SummaryDiagnosis": "summary",
    "WalksDiagnosis": "walks",
    "candidates": "naming",
    "decide": "naming",
    "diagnose": "discrepancy",
    "diagnose_summary": "summary",
    "diagnose_walks": "walks",
    "judge": "naming",
    "multi_start": "multistart",
    "observations": "measurement",
    "periodicity_test": "fit",
    "read_summary": "summary",
}

__all__ = sorted(_WHERE)


__getattr__, __dir__ = lazy_names(__name__, _WHERE, globals())

"""Every example in the package's docstrings runs and prints what it shows.

The examples are the first code a user copies from the reference pages
(docs/reference, ``help()``); each module's examples run here with the standard
``doctest`` runner, so an example that rots fails the suite.
"""

import doctest
import importlib
import pkgutil

import pytest

import bayesmodal

MODULES = sorted(m.name for m in pkgutil.walk_packages(bayesmodal.__path__, "bayesmodal.")
                 if m.name.rsplit(".", 1)[-1] != "__main__")


@pytest.mark.parametrize("name", MODULES)
def test_the_examples_run_as_shown(name):
    module = importlib.import_module(name)
    result = doctest.testmod(module, optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE,
                             verbose=False, report=True)
    assert result.failed == 0, f"{name}: {result.failed} of {result.attempted} examples fail"


def test_a_wrong_example_fails():
    """Negative control: the runner reports an example whose output differs."""
    def shown():
        """
        >>> 1 + 1
        3
        """
    finder, runner = doctest.DocTestFinder(), doctest.DocTestRunner(verbose=False)
    for test in finder.find(shown, "shown", globs={}):
        runner.run(test, out=lambda _: None)
    assert runner.summarize(verbose=False).failed == 1


def test_every_module_with_examples_is_collected():
    """The walk reaches the subpackages (examples exist deep in the tree)."""
    assert "bayesmodal.model.kernels.expm" in MODULES
    assert "bayesmodal.runs.folder" in MODULES

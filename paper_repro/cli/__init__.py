"""The command line, ``python -m paper_repro COMMAND``: one module per command, each with its
``HELP``, ``add_arguments(parser)`` and ``main(args)``.

=================  ==================================================================
``parser``         :func:`main`: the parser and the dispatch to the commands
``args``           argument types with a stated accepted range, checked output folders
``run``            fly one mission and save its result
``scene``          print a scene and D_{η,σ} against ½d²
``reproduce``      fly the paper's missions, run every notebook, write figures/
``study``          fly a study of the catalogue, write its table and figures
``tune``           tune the avoidance parameters with Optuna
``golden``         fly the golden flights and compare or write them
``regenerate``     make the stale evidence sets again, one job per core
``cache``          re-key the run cache after a layout change that moves no flight
``readme``         write or check the tables of the README and docs/
``book``           build the HTML book from docs/ and the executed notebooks
=================  ==================================================================
"""

from paper_repro.cli.parser import main

__all__ = ["main"]

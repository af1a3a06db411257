"""A griffe extension for the API reference: Sphinx roles in the docstrings read as code.

The docstrings cross-reference with Sphinx roles (``:func:`heatcurv.estimate```), which Markdown does
not know; mkdocstrings would print the role's name before the code. This turns each into plain code.
"""

import re

import griffe

ROLE = re.compile(r":(?:py:)?(?:func|class|meth|attr|data|mod|exc|obj|const):`~?([^`]+)`")


class SphinxRolesAsCode(griffe.Extension):
    """Rewrite ``:role:`name``` as ```name``` in every docstring griffe loads."""

    def on_instance(self, *, obj, **kwargs):
        if obj.docstring is not None:
            obj.docstring.value = ROLE.sub(r"``\1``", obj.docstring.value)

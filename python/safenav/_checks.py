# TEMPORARY for scenario.py (being rewritten), which imports `cut` from here:
# everything else imports safenav.validation.  Delete this file when scenario.py does too.
from .validation import cut  # noqa: F401

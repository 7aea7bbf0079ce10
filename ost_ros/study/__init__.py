"""``ost reproduce``: the paper's simulation study (§5: Table 1, Figs 7–11, Table 3) regenerated
from this code — design, parallel runs, tables, plots, and a report against the paper's numbers."""

"""One thesis experiment as data: Table 3.1 (effective manipulability ρ of the RHI, the PHANToM and Rehab).

An experiment returns a `Result` (tables of thesis-vs-rhi rows, arrays, notes) and draws nothing;
``rhi experiment ch3.table_3_1`` writes it as CSV/JSON with figures, ``rhi reproduce`` runs them all
into the HTML report. Here the ρ rows at the first target point are printed beside the thesis.

Run: ``python examples/thesis_table_3_1.py``. Needs only the core install.

Expected output (tests/test_examples.py checks every value to the tolerance given)::

    rho_rhi = 0.3752 +- 0.0001
    rho_rhi_thesis = 0.371 +- 0
    rho_phantom = 0.1876 +- 0.0001
    rho_phantom_thesis = 0.188 +- 0
    rho_rehab = 0.2960 +- 0.0001
    rho_rehab_thesis = 0.296 +- 0
    json_rows = 24 +- 0
"""

import json

from rhi.experiments.ch3 import table_3_1

result = table_3_1()
rows = {row.quantity: row for table in result.tables for row in table.rows}
for key, quantity in (("rho_rhi", "ρ RHI at (0.49, -0.22) (thesis configuration)"),
                      ("rho_phantom", "ρ PHANToM at (0.49, -0.22)"),
                      ("rho_rehab", "ρ Rehab at (0.49, -0.22)")):
    print(f"{key} = {rows[quantity].ours:.4f}")
    print(f"{key}_thesis = {rows[quantity].thesis}")

data = json.loads(json.dumps(result.to_json(arrays=False)))  # every number, JSON-serialisable
print(f"json_rows = {sum(len(t['rows']) for t in data['tables'])}")

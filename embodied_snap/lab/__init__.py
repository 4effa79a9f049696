"""The lab's side of the acquisition: `esnap lab plan` writes the sessions an operator records
(plan.py), `esnap lab acquire` records them on the arm over Protocol 2.0 (acquire.py). Only the CLI
imports it; it never imports the simulated rig."""

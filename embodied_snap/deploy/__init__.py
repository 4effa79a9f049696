"""Deployment (paper VI): the manifest, the goal schedule of one trial, and `esnap deploy`.

Everything here that `esnap deploy` loads (manifest, commands, controltable, client) needs only
numpy, dynamixel-sdk and the standard library, so it runs on the lab PC beside the arm
(tests/test_deploy.py holds it to that). The manifest builder (`build`) and Table II (`table2`, pandas and
the characterisation readers) are run by the workflow.
"""

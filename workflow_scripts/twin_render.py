"""Fig. 1a: the arm rendered from the simulated rig's own MuJoCo model (MUJOCO_GL=egl)."""

import sys

import matplotlib.image as mpimg

from embodied_snap.lineage.records import tracked
from embodied_snap.twin.render import render

sys.stderr = open(snakemake.log[0], "w")
with tracked(snakemake):
    mpimg.imsave(snakemake.output[0], render(), metadata={"Software": None})

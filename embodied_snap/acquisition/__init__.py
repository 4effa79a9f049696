"""The paper's acquisition protocol (section III): which programs each evidence set runs and each
group's draws. One home for the simulated rig (embodied_snap.twin) and the lab's arm
(embodied_snap.lab); it drives nothing itself."""

"""Drawing the scene: the off-screen GL backend (:mod:`mjnav.viz.gl`) and views, cameras and overlays
(:mod:`mjnav.viz.scene`). The Gymnasium environment renders through this package, so it never
imports evaluation. Kept empty so that :mod:`mjnav.viz.gl` runs before MuJoCo is imported."""

"""flow_bag: recorded data. synth (bags with exact ground truth), eval (replay through the node's pipeline,
report), play (publish over DDS). Everything in the package that imports rosbags lives here."""

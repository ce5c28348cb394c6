"""Everything that imports rclpy: the flow_node node (node.py), its parameter table (params.py) and its
diagnostics (diagnostics.py). The per-frame work lives in flow_node.pipeline."""

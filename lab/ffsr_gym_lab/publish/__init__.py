"""What the lab publishes besides the tables: the docs site's generated pages and the offline (Minari) datasets."""

"""Reading entities, agents, the ontology and static properties.

The catalogue's reads and writes live together in :mod:`toaster.db.catalog`; these are its
public reads, under the names the read path has always had.
"""

from toaster.db.catalog import agents, descendants, entities, ontology, properties

__all__ = ["agents", "descendants", "entities", "ontology", "properties"]

"""The world: the ProcTHOR house schema and its validation, the asset database (object
sizes and types), room classes and the mapping from room types to classes."""

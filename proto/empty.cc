// Placeholder until the service protos exist.

pub fn traverse() {}
